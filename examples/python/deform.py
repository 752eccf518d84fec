"""Deform a mesh with fibfluid and show it colored by displacement.

    pip install ./crates/python pyvista      # or meshio (then the picture needs pyvista)
    python examples/python/deform.py                                   # the bunny scene
    python examples/python/deform.py fixtures/scenes/liver-hanging.toml my-liver.stl

The first argument is a scene file (its constraints, loads and settings); the optional
second one a mesh (any format PyVista or meshio reads) that replaces the scene's mesh:
the scene's [[fix]] selectors are applied to it again, and vertex indices in the scene
(a [[force]]'s vertex) are its rows. Without PyVista the script still runs and prints the
report; with it, a window shows the rest shape (grey wireframe) and the deformed surface
colored by |u| (use --screenshot FILE.png to save the picture without a window).
"""

import argparse
import sys
from pathlib import Path

import numpy as np

import fibfluid

REPO = Path(__file__).resolve().parents[2]


def read_mesh(path):
    """Vertices (N, 3) and triangles (F, 3) of a mesh file, through PyVista or meshio."""
    try:
        import pyvista as pv

        mesh = pv.read(path).extract_surface().triangulate()
        return np.asarray(mesh.points, dtype=np.float64), mesh.faces.reshape(-1, 4)[:, 1:]
    except ImportError:
        import meshio

        mesh = meshio.read(path)
        return np.asarray(mesh.points, dtype=np.float64), mesh.get_cells_type("triangle")


def show(scene, result, screenshot=None):
    """The rest shape and the deformed surface colored by |u| (needs PyVista)."""
    try:
        import pyvista as pv
    except ImportError:
        print("(install pyvista to see the surface)")
        return
    faces = np.hstack([np.full((len(scene.faces), 1), 3), scene.faces]).ravel()
    rest = pv.PolyData(scene.vertices, faces)
    deformed = pv.PolyData(result.positions, faces)
    deformed["|u|"] = np.linalg.norm(result.displacement, axis=1)
    plotter = pv.Plotter(off_screen=screenshot is not None)
    plotter.add_mesh(rest, style="wireframe", color="grey", opacity=0.3)
    plotter.add_mesh(deformed, scalars="|u|", cmap="viridis", smooth_shading=True)
    plotter.add_text(f"{scene.name}: max |u| = {result.report['max_displacement']:.4g}", font_size=10)
    plotter.show(screenshot=screenshot)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene", nargs="?", default=REPO / "fixtures/scenes/bunny-pull.toml")
    parser.add_argument("mesh", nargs="?", help="a mesh replacing the scene's")
    parser.add_argument("--steps", type=int, help="load steps (default: the scene's)")
    parser.add_argument("--screenshot", help="save the picture here instead of opening a window")
    args = parser.parse_args()

    scene = fibfluid.Scene.load(args.scene)
    if args.mesh:
        vertices, faces = read_mesh(args.mesh)
        scene = scene.with_mesh(vertices, faces)
    if args.steps:
        scene.steps = args.steps
    result = fibfluid.run(scene, progress=True)
    r = result.report
    print(
        f"{r['scene']}: {r['vertices']} vertices, {r['steps']} steps ({r['backend']} / {r['mode']}), "
        f"max |u| = {r['max_displacement']:.6f}, volume drift {r['volume_drift']:.2e}, P = {result.pressure:.6f}"
    )
    show(scene, result, args.screenshot)


if __name__ == "__main__":
    try:
        main()
    except fibfluid.Error as e:
        sys.exit(f"error: {e}")
