#!/usr/bin/env python3
"""Compare a fibfluid run's surface displacement with a reference file (reference.py's output).

    python3 compare_surface.py MESH.obj SCALE OUT_DIR/deformed.obj REFERENCE.txt

fibfluid's deformed.obj has the input OBJ's vertices in order, in the mesh's unit after
`scale`; the displacement is deformed - SCALE * rest, over the vertices the faces use (the
reference's rows). Prints the relative L2 error sqrt(sum |u - u_ref|^2 / sum |u_ref|^2),
the largest |u|, the mean u of both and the ratio of its largest component, and the
mean error in five bands of height along that component's axis.
"""
import sys

import numpy as np

from reference import read_obj


def obj_vertices(path):
    return np.array([[float(x) for x in line.split()[1:4]] for line in open(path) if line.startswith("v ")])


def main():
    mesh, scale, deformed, ref = sys.argv[1:5]
    rest_all = obj_vertices(mesh)
    rest, _ = read_obj(mesh)
    used = np.array([np.flatnonzero(np.all(rest_all == r, axis=1))[0] for r in rest])
    u = obj_vertices(deformed)[used] - float(scale) * rest_all[used]
    r = np.loadtxt(ref)
    assert u.shape == r.shape, (u.shape, r.shape)
    e = np.linalg.norm(u - r, axis=1)
    print("vertices %d" % len(r))
    print("relative L2 error %.4f" % (np.linalg.norm(u - r) / np.linalg.norm(r)))
    print("largest |u|: fibfluid %.5e, reference %.5e, ratio %.4f"
          % (np.linalg.norm(u, axis=1).max(), np.linalg.norm(r, axis=1).max(),
             np.linalg.norm(u, axis=1).max() / np.linalg.norm(r, axis=1).max()))
    print("mean u: fibfluid %s, reference %s" % (np.array2string(u.mean(0), precision=5),
                                               np.array2string(r.mean(0), precision=5)))
    # along the axis of the largest mean displacement (gravity's)
    axis = int(np.argmax(np.abs(r.mean(0))))
    print("mean u_%s ratio %.4f, mean |u| ratio %.4f"
          % ("xyz"[axis], u[:, axis].mean() / r[:, axis].mean(),
             np.linalg.norm(u, axis=1).mean() / np.linalg.norm(r, axis=1).mean()))
    # where the difference sits: by height along that axis
    h = (rest[:, axis] - rest[:, axis].min()) / np.ptp(rest[:, axis])
    bands = np.minimum((h * 5).astype(int), 4)
    for b in range(5):
        m = bands == b
        print("  %s in [%.1f, %.1f] of the height: %4d vertices, |u - u_ref| mean %.3e, |u_ref| mean %.3e"
              % ("xyz"[axis], b / 5, (b + 1) / 5, m.sum(), e[m].mean(), np.linalg.norm(r[m], axis=1).mean()))


if __name__ == "__main__":
    main()
