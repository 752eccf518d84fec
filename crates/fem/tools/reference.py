#!/usr/bin/env python3
"""Independent reference for fibfluid-fem: quadratic-tetrahedron (P2) linear elasticity.

Tetrahedralizes a closed OBJ with TetGen (surface kept as is: every input vertex is a mesh
node with its own index) and solves  div sigma + rho g = 0  with scikit-fem, P2 displacement
elements, clamped where the surface is fixed: every vertex fixed by the rule below, and every
boundary facet whose three vertices are fixed (so the P2 edge nodes between fixed vertices
are fixed too).

Writes one line per surface vertex (OBJ order, the file's `v` lines that faces use, in
order): `ux uy uz`, with a header of `#` lines recording the inputs.

    python3 reference.py MESH.obj OUT.txt --young 5e4 --poisson 0.45 --density 1000 \
        --gravity 0 -9.81 0 --fix-above y 0.8      # fixed: vertices with y > 0.8
    python3 reference.py ... --fix-top y 0.08       # fixed: within 0.08 of the highest y
    python3 reference.py ... --fix-bottom y 0.08    # fixed: within 0.08 of the lowest y

Mesh: TetGen switches `pq<minratio>Y` (quality bound, surface kept: no Steiner point on it)
plus `a<maxvolume>` when given; `--minratio 1.2 --maxvolume V` refines the interior.

Needs: pip install scikit-fem tetgen meshio (numpy, scipy come with them).
"""
import argparse
import sys
import time

import numpy as np
import tetgen
from scipy.sparse.linalg import LinearOperator, cg, spsolve
from skfem import Basis, ElementTetP2, ElementVector, LinearForm, MeshTet, asm, condense, solve
from skfem.helpers import dot
from skfem.models.elasticity import lame_parameters, linear_elasticity


def read_obj(path):
    verts, faces = [], []
    for line in open(path):
        parts = line.split()
        if not parts:
            continue
        if parts[0] == "v":
            verts.append([float(x) for x in parts[1:4]])
        elif parts[0] == "f":
            idx = [int(p.split("/")[0]) for p in parts[1:]]
            idx = [i - 1 if i > 0 else len(verts) + i for i in idx]
            for k in range(1, len(idx) - 1):
                faces.append([idx[0], idx[k], idx[k + 1]])
    verts, faces = np.array(verts), np.array(faces)
    used = np.unique(faces)
    remap = -np.ones(len(verts), dtype=int)
    remap[used] = np.arange(len(used))
    return verts[used], remap[faces]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("mesh")
    ap.add_argument("out")
    ap.add_argument("--young", type=float, required=True)
    ap.add_argument("--poisson", type=float, required=True)
    ap.add_argument("--density", type=float, required=True)
    ap.add_argument("--gravity", type=float, nargs=3, default=[0.0, 0.0, 0.0])
    ap.add_argument("--fix-above", nargs=2, metavar=("AXIS", "VALUE"))
    ap.add_argument("--fix-top", nargs=2, metavar=("AXIS", "DEPTH"))
    ap.add_argument("--fix-bottom", nargs=2, metavar=("AXIS", "DEPTH"))
    ap.add_argument("--maxvolume", type=float, default=0.0, help="TetGen volume bound (0: none)")
    ap.add_argument("--direct", action="store_true", help="SuperLU instead of CG")
    ap.add_argument("--minratio", type=float, default=1.5, help="TetGen radius-edge bound (-q)")
    args = ap.parse_args()

    pos, tris = read_obj(args.mesh)
    n_surface = len(pos)
    tg = tetgen.TetGen(pos, tris)
    switches = "pq%gY" % args.minratio
    if args.maxvolume > 0:
        switches += "a%g" % args.maxvolume
    nodes, elems = tg.tetrahedralize(switches=switches + "Q")[:2]
    assert np.allclose(nodes[:n_surface], pos), "TetGen must keep the surface vertices first"
    mesh = MeshTet(np.ascontiguousarray(nodes.T), np.ascontiguousarray(elems.T))

    axis = {"x": 0, "y": 1, "z": 2}
    if args.fix_above:
        a, v = axis[args.fix_above[0]], float(args.fix_above[1])
        fixed = pos[:, a] > v
    elif args.fix_top:
        a, d = axis[args.fix_top[0]], float(args.fix_top[1])
        fixed = pos[:, a] >= pos[:, a].max() - d
    elif args.fix_bottom:
        a, d = axis[args.fix_bottom[0]], float(args.fix_bottom[1])
        fixed = pos[:, a] <= pos[:, a].min() + d
    else:
        sys.exit("give --fix-above, --fix-top or --fix-bottom")

    def solver(A, b):
        if args.direct:
            return spsolve(A, b)
        # Conjugate gradients, Jacobi-preconditioned, to a relative residual of 1e-10
        # (SuperLU's fill on fine 3D meshes is too large for this machine).
        d = 1.0 / A.diagonal()
        x, info = cg(A, b, rtol=1e-10, maxiter=100000, M=LinearOperator(A.shape, lambda r: d * r))
        assert info == 0, "CG did not converge"
        print("CG residual %.1e" % (np.linalg.norm(A @ x - b) / np.linalg.norm(b)))
        return x

    basis = Basis(mesh, ElementVector(ElementTetP2()), intorder=4)
    lam, mu = lame_parameters(args.young, args.poisson)
    K = asm(linear_elasticity(lam, mu), basis)
    rho_g = args.density * np.array(args.gravity)

    @LinearForm
    def weight(v, w):
        return rho_g[0] * v[0] + rho_g[1] * v[1] + rho_g[2] * v[2]

    f = asm(weight, basis)
    bfacets = mesh.boundary_facets()
    fixed_node = np.zeros(mesh.nvertices, dtype=bool)
    fixed_node[:n_surface] = fixed
    clamp_facets = bfacets[np.all(fixed_node[mesh.facets[:, bfacets]], axis=0)]
    dofs = set(basis.get_dofs(facets=clamp_facets).all().tolist())
    dofs |= set(basis.nodal_dofs[:, np.flatnonzero(fixed_node)].ravel().tolist())
    D = np.array(sorted(dofs), dtype=int)
    t0 = time.time()
    u = solve(*condense(K, f, D=D), solver=solver)
    print("solved %d dofs in %.1f s" % (basis.N, time.time() - t0))
    disp = u[basis.nodal_dofs[:, :n_surface]].T

    with open(args.out, "w") as out:
        out.write("# P2 tetrahedra (scikit-fem), TetGen mesh: %d nodes, %d tets, %d dofs\n"
                  % (mesh.nvertices, mesh.nelements, basis.N))
        out.write("# %s\n" % " ".join(sys.argv[1:]))
        out.write("# TetGen switches: %s\n" % switches)
        out.write("# fixed surface vertices: %d; clamped facets: %d\n" % (fixed.sum(), len(clamp_facets)))
        for d in disp:
            out.write("%.12e %.12e %.12e\n" % tuple(d))
    print("max |u| = %.6e, tets %d" % (np.linalg.norm(disp, axis=1).max(), mesh.nelements))


if __name__ == "__main__":
    main()
