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
`--subdivide N` splits every surface triangle 1-to-4 at its edge midpoints N times before
TetGen (same surface, flat pieces; the original vertices keep their indices and are the
only ones reported), so the tets at the surface, and at the clamp's edge, can get finer than
the input triangles; `--refine-clamp LEVELS RADIUS` then splits, LEVELS more times, the
triangles within RADIUS (halved at each level) of a fixed vertex (the displacement is
singular at the clamp's edge; red-green refinement, so the surface stays conforming). The
clamped surface stays the same set: a new surface node is clamped iff it lies on an input
triangle whose three vertices are fixed, and a boundary facet is clamped iff it is a piece
of such a triangle.

Solver: conjugate gradients to a relative residual of 1e-10, preconditioned by Jacobi, or
(`--solver amg`) by a smoothed-aggregation algebraic multigrid V-cycle built on the six
rigid-body modes (pyamg), or SuperLU (`--solver direct`).

`--model neo-hookean` solves fibfluid's compressible neo-Hookean tissue instead (same mesh,
clamp and loads; Newton's method with load stepping, see reference_nh.py, which states the
energy; its linear systems by AMG-CG, or SuperLU with `--solver direct`). `--scale S`
multiplies the OBJ's coordinates by S first (the clamp's values, `--maxvolume` and the
written displacements are then in the scaled unit). With the neo-Hookean model,
`--grasp VERTEX RADIUS TX TY TZ` holds the input vertices within RADIUS of input vertex
VERTEX (fibfluid's `[[grasp]]` patch) and the P2 nodes of the boundary facets that are
pieces of input triangles with three patch vertices at the translation ramped with the
load; `--plate AXIS SIGN POSITION TRAVEL` (repeatable) adds a frictionless rigid plate, the
plane `x[AXIS] = POSITION + SIGN t TRAVEL` with the body on its SIGN side (an active set
of nodes held on the plane, reference_nh.contact_solve), and the plates' forces go into
the header's first line.

Needs: pip install scikit-fem tetgen meshio (numpy, scipy come with them); pyamg for
`--solver amg`.
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


def subdivide(pos, tris, parent):
    """1-to-4 midpoint split of every triangle; new vertices are appended, so the input
    vertices keep their indices. `parent[t]` is the input triangle piece `t` came from."""
    pos = list(map(tuple, pos))
    mid = {}

    def midpoint(a, b):
        key = (min(a, b), max(a, b))
        if key not in mid:
            mid[key] = len(pos)
            pos.append(tuple((np.array(pos[a]) + np.array(pos[b])) / 2))
        return mid[key]

    out, out_parent = [], []
    for (a, b, c), p in zip(tris, parent):
        ab, bc, ca = midpoint(a, b), midpoint(b, c), midpoint(c, a)
        out += [[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]
        out_parent += [p] * 4
    return np.array(pos), np.array(out), np.array(out_parent)


def refine_near(pos, tris, parent, centres, radius):
    """Red-green refinement: every triangle whose centroid is within `radius` of a point of
    `centres` is split 1-to-4 at its edge midpoints, so is every triangle with two or more
    split edges, and a triangle with one split edge is split in two at its midpoint (the
    surface stays conforming). New vertices are appended; `parent` follows the pieces."""
    from scipy.spatial import cKDTree

    d, _ = cKDTree(centres).query(pos[tris].mean(axis=1))
    red = d < radius
    edge_key = lambda a, b: (min(a, b), max(a, b))
    while True:
        split = {edge_key(*e) for t in tris[red] for e in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0]))}
        count = np.array([sum(edge_key(*e) in split for e in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0])))
                          for t in tris])
        grow = (count >= 2) & ~red
        if not grow.any():
            break
        red |= grow
    pos = list(map(tuple, pos))
    mid = {}
    for a, b in sorted(split):
        mid[(a, b)] = len(pos)
        pos.append(tuple((np.array(pos[a]) + np.array(pos[b])) / 2))
    out, out_parent = [], []
    for t, p, r in zip(tris.tolist(), parent, red):
        a, b, c = t
        if r:
            ab, bc, ca = mid[edge_key(a, b)], mid[edge_key(b, c)], mid[edge_key(c, a)]
            pieces = [[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]
        elif edge_key(a, b) in mid:
            m = mid[edge_key(a, b)]
            pieces = [[a, m, c], [m, b, c]]
        elif edge_key(b, c) in mid:
            m = mid[edge_key(b, c)]
            pieces = [[a, b, m], [a, m, c]]
        elif edge_key(c, a) in mid:
            m = mid[edge_key(c, a)]
            pieces = [[a, b, m], [m, b, c]]
        else:
            pieces = [t]
        out += pieces
        out_parent += [p] * len(pieces)
    return np.array(pos), np.array(out), np.array(out_parent)


def rigid_modes(basis):
    """The six rigid-body displacements at every dof of a vector basis, (N, 6)."""
    comp = np.empty(basis.N, dtype=int)
    x = basis.doflocs  # (3, N): where each dof sits
    for c in range(3):
        comp[basis.nodal_dofs[c]] = c
        comp[basis.edge_dofs[c]] = c
    assert len(basis.nodal_dofs[0]) + len(basis.edge_dofs[0]) == basis.N // 3
    B = np.zeros((basis.N, 6))
    for c in range(3):
        B[comp == c, c] = 1.0
    # rotation about axis k: u = e_k x (x - x0)
    x0 = x.mean(axis=1)
    for k, (i, j) in enumerate([(1, 2), (2, 0), (0, 1)]):
        # (e_k x r)_i = -r_j, (e_k x r)_j = r_i
        B[comp == i, 3 + k] = -(x[j, comp == i] - x0[j])
        B[comp == j, 3 + k] = x[i, comp == j] - x0[i]
    return B


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
    ap.add_argument("--solver", choices=["jacobi", "amg", "direct"], default="jacobi",
                    help="CG preconditioner (jacobi, amg) or SuperLU (direct)")
    ap.add_argument("--subdivide", type=int, default=0,
                    help="split the surface triangles 1-to-4 this many times before TetGen")
    ap.add_argument("--refine-clamp", nargs=2, metavar=("LEVELS", "RADIUS"),
                    help="after --subdivide, LEVELS more splits of the triangles within RADIUS "
                         "(halved at each level) of a fixed vertex (red-green, conforming)")
    ap.add_argument("--minratio", type=float, default=1.5, help="TetGen radius-edge bound (-q)")
    ap.add_argument("--scale", type=float, default=1.0, help="multiply the OBJ's coordinates by this")
    ap.add_argument("--model", choices=["linear", "neo-hookean"], default="linear")
    ap.add_argument("--load-steps", type=int, default=4, help="neo-Hookean: initial load increments")
    ap.add_argument("--tol", type=float, default=1e-8, help="neo-Hookean: relative residual")
    ap.add_argument("--plate", nargs=4, action="append", metavar=("AXIS", "SIGN", "POSITION", "TRAVEL"),
                    help="neo-Hookean: a frictionless rigid plate, the plane x[AXIS] = POSITION + SIGN t "
                         "TRAVEL (scaled unit), the body on its SIGN side (+1 or -1); repeatable")
    ap.add_argument("--grasp", nargs=5, type=float, metavar=("VERTEX", "RADIUS", "TX", "TY", "TZ"),
                    help="neo-Hookean: the surface within RADIUS of input vertex VERTEX (scaled unit) "
                         "moved by (TX, TY, TZ) at the full load, as fibfluid's [[grasp]]")
    args = ap.parse_args()

    pos, tris = read_obj(args.mesh)
    pos = pos * args.scale
    n_surface = len(pos)
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

    fine_pos, fine_tris, parent = pos, tris, np.arange(len(tris))
    for _ in range(args.subdivide):
        fine_pos, fine_tris, parent = subdivide(fine_pos, fine_tris, parent)
    if args.refine_clamp:
        # Around the clamp (the displacement is singular at its edge).
        levels, radius = int(args.refine_clamp[0]), float(args.refine_clamp[1])
        for k in range(levels):
            fine_pos, fine_tris, parent = refine_near(fine_pos, fine_tris, parent, pos[fixed], radius / 2**k)
    print("surface: %d triangles, %d vertices" % (len(fine_tris), len(fine_pos)))
    tg = tetgen.TetGen(fine_pos, fine_tris)
    switches = "pq%gY" % args.minratio
    if args.maxvolume > 0:
        switches += "a%g" % args.maxvolume
    t0 = time.time()
    nodes, elems = tg.tetrahedralize(switches=switches + "Q")[:2]
    print("TetGen: %d tets in %.1f s" % (len(elems), time.time() - t0))
    assert np.allclose(nodes[: len(fine_pos)], fine_pos), "TetGen must keep the surface vertices first"
    mesh = MeshTet(np.ascontiguousarray(nodes.T), np.ascontiguousarray(elems.T))
    if args.model == "neo-hookean":
        return neo_hookean(args, mesh, pos, tris, fine_tris, parent, fixed, switches)

    basis = Basis(mesh, ElementVector(ElementTetP2()), intorder=4)
    modes = rigid_modes(basis)

    def solver(A, b, I):
        if args.solver == "direct":
            return spsolve(A, b)
        # Conjugate gradients to a relative residual of 1e-10 (SuperLU's fill on fine 3D
        # meshes is too large for this machine).
        if args.solver == "amg":
            import pyamg

            ml = pyamg.smoothed_aggregation_solver(A.tocsr(), B=modes[I], symmetry="hermitian")
            M = ml.aspreconditioner(cycle="V")
        else:
            d = 1.0 / A.diagonal()
            M = LinearOperator(A.shape, lambda r: d * r)
        its = [0]

        def count(_):
            its[0] += 1

        x, info = cg(A, b, rtol=1e-10, maxiter=100000, M=M, callback=count)
        assert info == 0, "CG did not converge"
        print("CG: %d iterations, residual %.1e" % (its[0], np.linalg.norm(A @ x - b) / np.linalg.norm(b)))
        return x

    lam, mu = lame_parameters(args.young, args.poisson)
    K = asm(linear_elasticity(lam, mu), basis)
    rho_g = args.density * np.array(args.gravity)

    @LinearForm
    def weight(v, w):
        return rho_g[0] * v[0] + rho_g[1] * v[1] + rho_g[2] * v[2]

    f = asm(weight, basis)
    # Clamped: the boundary facets that are (pieces of) input triangles with three fixed
    # vertices, and every fixed input vertex.
    clamp_facets, clamped_tri, lone = clamp(mesh, tris, fine_tris, parent, fixed)
    dofs = set(basis.get_dofs(facets=clamp_facets).all().tolist())
    dofs |= set(basis.nodal_dofs[:, np.flatnonzero(fixed)].ravel().tolist())
    D = np.array(sorted(dofs), dtype=int)
    I = basis.complement_dofs(D)
    t0 = time.time()
    u = solve(*condense(K, f, D=D), solver=lambda A, b: solver(A, b, I))
    print("solved %d dofs in %.1f s" % (basis.N, time.time() - t0))
    disp = u[basis.nodal_dofs[:, :n_surface]].T

    write_surface(args.out, "P2 tetrahedra (scikit-fem), TetGen mesh: %d nodes, %d tets, %d dofs"
                  % (mesh.nvertices, mesh.nelements, basis.N),
                  switches, (fixed.sum(), len(lone), clamped_tri.sum(), len(clamp_facets)), disp)
    print("max |u| = %.6e, tets %d" % (np.linalg.norm(disp, axis=1).max(), mesh.nelements))


def write_surface(path, what, switches, clamp_counts, disp):
    """Writes a golden: `#` header lines (what was solved, the command, TetGen's switches,
    the clamp's counts: fixed vertices, those in no clamped triangle, clamped input
    triangles, clamped facets), then one `ux uy uz` line per input vertex (metres)."""
    with open(path, "w") as out:
        out.write("# %s\n" % what)
        out.write("# %s\n" % " ".join(sys.argv[1:]))
        out.write("# TetGen switches: %s\n" % switches)
        out.write("# fixed surface vertices: %d (%d in no clamped triangle); clamped input triangles: %d,"
                  " clamped facets: %d\n" % clamp_counts)
        for d in disp:
            out.write("%.12e %.12e %.12e\n" % tuple(d))


def clamp(mesh, tris, fine_tris, parent, fixed):
    """The boundary facets that are (pieces of) input triangles with three fixed vertices,
    and the fixed input vertices in no such triangle (as main's linear path selects)."""
    bfacets = mesh.boundary_facets()
    clamped_tri = np.all(fixed[tris], axis=1)
    clamped_piece = {tuple(sorted(t)) for t, p in zip(fine_tris.tolist(), parent) if clamped_tri[p]}
    is_clamped = np.array([tuple(sorted(t)) in clamped_piece for t in mesh.facets[:, bfacets].T.tolist()],
                          dtype=bool)
    clamp_facets = bfacets[is_clamped]
    assert len(clamp_facets) == len(clamped_piece), "every clamped piece is a boundary facet"
    lone = np.setdiff1d(np.flatnonzero(fixed), np.unique(tris[clamped_tri]))
    return clamp_facets, clamped_tri, lone


def neo_hookean(args, mesh, pos, tris, fine_tris, parent, fixed, switches):
    import reference_nh as nh

    n_surface = len(pos)
    clamp_facets, clamped_tri, lone = clamp(mesh, tris, fine_tris, parent, fixed)
    t0 = time.time()
    body = nh.Body(mesh, args.young, args.poisson)
    sD = np.union1d(body.sb.get_dofs(facets=clamp_facets).all(), body.sb.nodal_dofs[0, np.flatnonzero(fixed)])
    D = body.vector_dofs(sD)
    uD = None
    if args.grasp:
        D, uD = grasped(args.grasp, body, mesh, pos, tris, fine_tris, parent, fixed, D)
    f = body.load(args.density * np.array(args.gravity))
    solver = "direct" if args.solver == "direct" else "amg"
    note = ""
    if args.plate:
        axis = {"x": 0, "y": 1, "z": 2}
        plates = [(axis[a], float(s), float(p), float(d)) for a, s, p, d in args.plate]
        u, history, forces = nh.contact_solve(body, f, D, plates, steps=args.load_steps, tol=args.tol,
                                              solver=solver)
        note = "; plate forces on the body along their normals %s N" % " ".join("%.6g" % x for x in forces)
        print(note[2:])
    else:
        u, history = nh.newton_solve(body, f, D, uD=uD, steps=args.load_steps, tol=args.tol, solver=solver)
    seconds = time.time() - t0
    disp = body.nodal(u)[:n_surface]
    iterations = sum(h[1] for h in history)
    print("neo-Hookean: %d dofs, %d load steps, %d Newton iterations, %.1f s"
          % (body.N, len(history), iterations, seconds))
    write_surface(args.out, "neo-Hookean (reference_nh.py), P2 tetrahedra (scikit-fem), TetGen mesh: %d nodes,"
                  " %d tets, %d dofs; %d load steps, %d Newton iterations, %.0f s%s"
                  % (mesh.nvertices, mesh.nelements, body.N, len(history), iterations, seconds, note),
                  switches, (fixed.sum(), len(lone), clamped_tri.sum(), len(clamp_facets)), disp)
    print("max |u| = %.6e, mean u = %s, tets %d"
          % (np.linalg.norm(disp, axis=1).max(), np.array2string(disp.mean(axis=0), precision=6), mesh.nelements))


def grasped(grasp, body, mesh, pos, tris, fine_tris, parent, fixed, D):
    """The held dofs with a grasp's patch added (every input vertex within the radius of the
    centre vertex, as fibfluid's `Grasp::patch`, and the P2 nodes of the boundary facets
    that are pieces of input triangles with three patch vertices), and their prescribed
    displacements at the full load (the translation on the patch, 0 on the clamp)."""
    centre, radius, translation = int(grasp[0]), grasp[1], np.array(grasp[2:5])
    patch = np.linalg.norm(pos - pos[centre], axis=1) <= radius
    patch[centre] = True
    assert not np.any(patch & fixed), "the grasp's patch holds a clamped vertex"
    facets = clamp(mesh, tris, fine_tris, parent, patch)[0]
    sG = np.union1d(body.sb.get_dofs(facets=facets).all(), body.sb.nodal_dofs[0, np.flatnonzero(patch)])
    G = body.vector_dofs(sG)
    print("grasp: %d input vertices, %d boundary facets, %d dofs" % (patch.sum(), len(facets), len(G)))
    held = np.concatenate([D, G])
    uD = np.concatenate([np.zeros(len(D)), translation[G % 3]])
    order = np.argsort(held)
    return held[order], uD[order]


if __name__ == "__main__":
    main()
