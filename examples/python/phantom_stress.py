"""Compress the segmented phantom between plates and show the von Mises stress inside it.

    pip install ./crates/python pyvista
    python examples/python/phantom_stress.py                          # a window
    python examples/python/phantom_stress.py --screenshot stress.png  # off screen

The scene is fixtures/scenes/phantom-compression.toml: the synthetic label image
fixtures/images/phantom.nii.gz (fat, label 1, with a stiff lesion, label 2) resting on a
detector plate and pressed 3.5 mm by a paddle, solved by the neo-Hookean finite-element
method. The script prints the largest and the median von Mises stress of each material
(over the cells at least half inside the body's surface: the grid's cells overhang it),
then draws the deformed grid cut in half through the lesion's centre, its cells coloured
by the von Mises stress (kPa), the lesion's cells (every [[region]]'s) outlined in white,
and the plates where they end. Another scene file may be given instead. The arrays are SI
(metres, Pa); the picture shows kPa and millimetres.
"""

import argparse
import sys
from pathlib import Path

import numpy as np

import fibfluid

REPO = Path(__file__).resolve().parents[2]
SCENE = REPO / "fixtures" / "scenes" / "phantom-compression.toml"
#: Cells less filled than this are left out of the statistics: a cell of the embedded grid
#: that is mostly outside the surface (at the paddle's rim) carries the largest and least
#: meaningful stresses.
MIN_FILL = 0.5


def summary(result):
    """Per material, over the cells at least MIN_FILL inside the body: the number of cells,
    the largest and the median von Mises stress (Pa)."""
    volume = result.volume
    rows = {}
    for mid in np.unique(volume.material_id):
        s = volume.von_mises_stress[(volume.material_id == mid) & (volume.fill >= MIN_FILL)]
        if s.size:
            rows[material(result, mid)] = (s.size, float(s.max()), float(np.median(s)))
    return rows


def material(result, mid):
    """A material's name: "tissue" for the scene's [tissue] (the phantom's fat), else its
    [[region]]'s name (the phantom's lesion)."""
    regions = result.report.get("regions", [])
    return "tissue" if mid == 0 else regions[int(mid) - 1]["name"]


def plates(scene_path):
    """Each ``[[plate]]`` of the scene file at the end of its travel: (point, normal), m.
    Empty without tomllib (Python 3.11) or without plates."""
    try:
        import tomllib
    except ImportError:
        return []
    with open(scene_path, "rb") as f:
        table = tomllib.load(f)
    out = []
    for p in table.get("plate", []):
        normal = np.asarray(p["normal"], dtype=float)
        normal /= np.linalg.norm(normal)
        out.append((np.asarray(p["point"], dtype=float) + p.get("travel", 0.0) * normal, normal))
    return out


def show(result, scene_path, screenshot=None):
    """The deformed grid cut through the lesion, coloured by the von Mises stress."""
    try:
        import pyvista as pv
    except ImportError:
        print("(install pyvista to see the stress: pip install pyvista)")
        return
    grid = result.volume_to_pyvista()
    grid.cell_data["von Mises (kPa)"] = grid.cell_data["von_mises_stress"] / 1000.0
    grid = grid.scale(1000.0)  # mm on screen (a copy: the result's arrays stay in metres)
    lesion = grid.threshold([0.5, float(grid.cell_data["material_id"].max()) + 0.5], scalars="material_id")
    centre = np.asarray(lesion.center if lesion.n_cells else grid.center)
    # The half of the body behind the plane z = the lesion's centre, whole cells (crinkle),
    # so the cut face shows the cells' own values.
    half = grid.clip(normal=(0.0, 0.0, 1.0), origin=centre, crinkle=True)
    lesion_half = lesion.clip(normal=(0.0, 0.0, 1.0), origin=centre, crinkle=True)

    plotter = pv.Plotter(off_screen=screenshot is not None, window_size=(1000, 720))
    plotter.set_background("white")
    # The colours span the well-filled cells' stresses; the rim's nearly empty cells saturate.
    filled = grid.cell_data["fill"] >= MIN_FILL
    top = float(grid.cell_data["von Mises (kPa)"][filled].max())
    plotter.add_mesh(
        half, scalars="von Mises (kPa)", cmap="inferno", clim=(0.0, top), show_edges=True,
        edge_color="#303030", line_width=0.5,
        scalar_bar_args={"title": "von Mises stress (kPa)", "color": "black", "fmt": "%.2f"},
    )
    if lesion.n_cells:
        outline = lesion_half.extract_feature_edges(boundary_edges=True, feature_edges=True,
                                                    non_manifold_edges=False, manifold_edges=False)
        plotter.add_mesh(outline, color="white", line_width=3)
    size = 1.15 * max(grid.bounds[1] - grid.bounds[0], grid.bounds[5] - grid.bounds[4])
    for point, normal in plates(scene_path):
        # The plate's plane at the end of its travel, centred over the body.
        at = np.asarray(grid.center) + np.dot(point * 1000.0 - grid.center, normal) * normal
        plotter.add_mesh(pv.Plane(center=at, direction=normal, i_size=size, j_size=size),
                         color="#7f93a8", opacity=0.25)
    rows = summary(result)
    r = result.report
    lines = [f"{r['scene']}: {r['tissue']['model']} FEM, largest displacement {r['max_displacement'] * 1000:.1f} mm"]
    lines += [f"{name}: max {mx / 1000:.2f} kPa, median {md / 1000:.2f} kPa ({n} cells at least half filled)"
              for name, (n, mx, md) in rows.items()]
    text = "\n".join(lines)
    plotter.add_text(text, font_size=10, color="black", position="upper_left")
    plotter.camera_position = "xy"
    plotter.camera.azimuth = -30.0
    plotter.camera.elevation = 6.0
    plotter.camera.zoom(1.15)
    plotter.show(screenshot=screenshot)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene", nargs="?", default=SCENE, help="a scene with [[region]]s (default: the phantom)")
    parser.add_argument("--screenshot", help="save the picture here (PNG) instead of opening a window")
    args = parser.parse_args()

    result = fibfluid.run(fibfluid.Scene.load(args.scene), method="fem")
    volume = result.volume
    print(f"{result.report['scene']}: {volume.n_cells} hexahedra, {volume.n_nodes} nodes, "
          f"max |u| = {result.report['max_displacement'] * 1000:.2f} mm")
    print(f"von Mises stress over the cells at least {MIN_FILL:.0%} inside the body:")
    for name, (n, mx, md) in summary(result).items():
        print(f"  {name:8s} {n:5d} cells  max {mx:8.1f} Pa  median {md:8.1f} Pa")
    k = int(np.argmax(volume.von_mises_stress))
    print(f"the largest of all cells: {volume.von_mises_stress[k]:.1f} Pa in a {material(result, volume.material_id[k])} "
          f"cell {volume.fill[k]:.1%} inside the body")
    show(result, args.scene, args.screenshot)


if __name__ == "__main__":
    try:
        main()
    except fibfluid.Error as e:
        sys.exit(f"error: {e}")
