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

Needs: pip install scikit-fem tetgen meshio (numpy, scipy come with them).
"""
import argparse
import sys

import numpy as np
import tetgen
from scipy.sparse.linalg import spsolve
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
    ap.add_argument("--maxvolume", type=float, default=0.0, help="TetGen volume bound (0: none)")
    args = ap.parse_args()

    pos, tris = read_obj(args.mesh)
    n_surface = len(pos)
    tg = tetgen.TetGen(pos, tris)
    opts = dict(order=1, quality=True, minratio=1.5, nobisect=True, verbose=0)
    if args.maxvolume > 0:
        opts.update(maxvolume=args.maxvolume, fixedvolume=True)
    nodes, elems = tg.tetrahedralize(**opts)[:2]
    assert np.allclose(nodes[:n_surface], pos), "TetGen must keep the surface vertices first"
    mesh = MeshTet(np.ascontiguousarray(nodes.T), np.ascontiguousarray(elems.T))

    axis = {"x": 0, "y": 1, "z": 2}
    if args.fix_above:
        a, v = axis[args.fix_above[0]], float(args.fix_above[1])
        fixed = pos[:, a] > v
    elif args.fix_top:
        a, d = axis[args.fix_top[0]], float(args.fix_top[1])
        fixed = pos[:, a] >= pos[:, a].max() - d
    else:
        sys.exit("give --fix-above or --fix-top")

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
    u = solve(*condense(K, f, D=D), solver=spsolve)
    disp = u[basis.nodal_dofs[:, :n_surface]].T

    with open(args.out, "w") as out:
        out.write("# P2 tetrahedra (scikit-fem), TetGen mesh: %d nodes, %d tets, %d dofs\n"
                  % (mesh.nvertices, mesh.nelements, basis.N))
        out.write("# %s\n" % " ".join(sys.argv[1:]))
        out.write("# fixed surface vertices: %d; clamped facets: %d\n" % (fixed.sum(), len(clamp_facets)))
        for d in disp:
            out.write("%.12e %.12e %.12e\n" % tuple(d))
    print("max |u| = %.6e, tets %d" % (np.linalg.norm(disp, axis=1).max(), mesh.nelements))


if __name__ == "__main__":
    main()
