//! The finite-element bodies of the cases, built and solved through `fibfluid-fem`'s
//! public API as a user's program would; each returns the measured quantity.

use fibfluid_fem::hyper::{CellMaterial, HyperBody, HyperCell, NewtonSettings, Pressure, RigidPlate};
use fibfluid_fem::{FemOptions, Loads, Result, Tissue};
use fibfluid_geometry::{Vec3, box_surface, hollow_icosphere, icosphere};

/// A unit cube (`resolution` cells a side, one surface vertex per node) held on its three
/// coordinate planes along their normals (symmetry planes), pulled on the far faces of the
/// first `loaded` axes by a dead nominal stress `p` (Pa): the mean stretch of the far face
/// of axis x.
pub fn pulled_cube(tissue: &Tissue, resolution: usize, loaded: usize, p: f64) -> Result<f64> {
    let (pos, tris) = box_surface([0.0; 3], [resolution; 3], 1.0 / resolution as f64);
    let fixed: Vec<[bool; 3]> = pos.iter().map(|x| x.map(|c| c == 0.0)).collect();
    let on_far_face = |t: &[u32; 3], axis: usize| t.iter().all(|&v| pos[v as usize][axis] == 1.0);
    let pressures: Vec<Pressure> = (0..loaded)
        .map(|axis| Pressure {
            value: -p,
            faces: tris.iter().filter(|t| on_far_face(t, axis)).copied().collect(),
        })
        .collect();
    let options = FemOptions { resolution, ..FemOptions::default() };
    let mut body =
        HyperBody::from_surface(&pos, &tris, tissue, &fixed, &options)?.with_pressures(&pressures)?;
    let sol = body.solve(&Loads::default(), &[])?;
    let far: Vec<usize> = (0..pos.len()).filter(|&v| pos[v][0] == 1.0).collect();
    Ok(1.0 + far.iter().map(|&v| sol.surface_displacements[v][0]).sum::<f64>() / far.len() as f64)
}

/// One cell of edge 1 m with every node on the homogeneous simple shear `x += gamma y`: the
/// shear force its nodes on the face `y = 1` carry (N), the element's `P_xy` on that face
/// (NaN if the law refuses the deformation).
pub fn sheared_cell(tissue: &Tissue, gamma: f64) -> f64 {
    let cell = HyperCell::new(1.0);
    let corner = |b: usize| [(b & 1) as f64, ((b >> 1) & 1) as f64, ((b >> 2) & 1) as f64];
    let u: [Vec3; 8] = std::array::from_fn(|b| [gamma * corner(b)[1], 0.0, 0.0]);
    let Some(t) = cell.tangent(&CellMaterial::of(tissue), &u, 1.0, false) else { return f64::NAN };
    (0..8).filter(|b| corner(*b)[1] == 1.0).map(|b| t.gradient[3 * b]).sum()
}

/// Each vertex on a coordinate plane held along that plane's normal: the symmetry planes of
/// a body centred at the origin (no rigid motion; nothing against a symmetric deformation).
fn symmetry_planes(positions: &[Vec3], size: f64) -> Vec<[bool; 3]> {
    positions.iter().map(|p| p.map(|c| c.abs() < 1e-9 * size)).collect()
}

/// The thick sphere of radii `a` and `b` (icospheres of `level`) under the follower
/// pressure `p` (Pa) in its cavity, solved with `newton`: the mean inner stretch.
pub fn inflated_sphere(
    tissue: &Tissue,
    (a, b, level): (f64, f64, u32),
    resolution: usize,
    p: f64,
    newton: NewtonSettings,
) -> Result<f64> {
    let (positions, outer_faces, cavity_faces) = hollow_icosphere(a, b, level);
    let mut triangles = outer_faces;
    triangles.extend_from_slice(&cavity_faces);
    let fixed = symmetry_planes(&positions, b);
    let options = FemOptions { resolution, ..FemOptions::default() };
    let pressure = Pressure { value: p, faces: cavity_faces.clone() };
    let mut body = HyperBody::from_surface(&positions, &triangles, tissue, &fixed, &options)?
        .with_pressures(&[pressure])?
        .with_settings(newton);
    let sol = body.solve(&Loads::default(), &[])?;
    Ok(mean_stretch(&positions, &sol.surface_displacements, &cavity_faces, 3))
}

/// The mean over the vertices of `faces` of their distance from the origin deformed over
/// at rest, measured in the first `axes` coordinates (3: from the centre, 2: from the z
/// axis).
fn mean_stretch(positions: &[Vec3], displacements: &[Vec3], faces: &[[u32; 3]], axes: usize) -> f64 {
    let radius = |p: Vec3| p[..axes].iter().map(|c| c * c).sum::<f64>().sqrt();
    let mut vertices: Vec<usize> = faces.iter().flatten().map(|&v| v as usize).collect();
    vertices.sort_unstable();
    vertices.dedup();
    let stretch = |v: usize| {
        let (x, u) = (positions[v], displacements[v]);
        radius([x[0] + u[0], x[1] + u[1], x[2] + u[2]]) / radius(x)
    };
    vertices.iter().map(|&v| stretch(v)).sum::<f64>() / vertices.len() as f64
}

/// A hollow cylinder about z (radii `a` < `b`, length `length` centred on z = 0), closed by
/// flat annular caps: `segments` around (a multiple of 4, so vertices lie on the planes
/// x = 0 and y = 0), `layers` along z, `rings` across each cap. Returns the positions, every
/// face (outward from the material) and the inner (cavity) faces, which face the hole.
fn hollow_cylinder(
    (a, b, length): (f64, f64, f64),
    (segments, layers, rings): (usize, usize, usize),
) -> (Vec<Vec3>, Vec<[u32; 3]>, Vec<[u32; 3]>) {
    let mut positions = Vec::new();
    // Rings of `segments` vertices: the inner and outer walls' at every layer, and the
    // caps' rings strictly inside the wall at the two ends.
    let mut ring_at = |r: f64, z: f64| {
        let first = positions.len() as u32;
        positions.extend((0..segments).map(|j| {
            let t = std::f64::consts::TAU * j as f64 / segments as f64;
            [r * t.cos(), r * t.sin(), z]
        }));
        first
    };
    let z = |l: usize| length * (l as f64 / layers as f64 - 0.5);
    let inner: Vec<u32> = (0..=layers).map(|l| ring_at(a, z(l))).collect();
    let outer: Vec<u32> = (0..=layers).map(|l| ring_at(b, z(l))).collect();
    let radius = |k: usize| a + (b - a) * k as f64 / rings as f64;
    let cap = |l: usize, ring_at: &mut dyn FnMut(f64, f64) -> u32| -> Vec<u32> {
        let mut across = vec![inner[l]];
        across.extend((1..rings).map(|k| ring_at(radius(k), z(l))));
        across.push(outer[l]);
        across
    };
    let (bottom, top) = (cap(0, &mut ring_at), cap(layers, &mut ring_at));
    let next = |j: usize| (j + 1) % segments;
    // The quad (p0 + j, p0 + j + 1, p1 + j + 1, p1 + j) as two triangles, turned by `flip`.
    let strip = |p0: u32, p1: u32, flip: bool, out: &mut Vec<[u32; 3]>| {
        for j in 0..segments {
            let (i0, i1, i2, i3) = (p0 + j as u32, p0 + next(j) as u32, p1 + next(j) as u32, p1 + j as u32);
            if flip {
                out.extend([[i0, i2, i1], [i0, i3, i2]]);
            } else {
                out.extend([[i0, i1, i2], [i0, i2, i3]]);
            }
        }
    };
    let (mut faces, mut cavity) = (Vec::new(), Vec::new());
    for l in 0..layers {
        strip(outer[l], outer[l + 1], false, &mut faces);
        strip(inner[l], inner[l + 1], true, &mut cavity);
    }
    for k in 0..rings {
        strip(top[k], top[k + 1], false, &mut faces);
        strip(bottom[k], bottom[k + 1], true, &mut faces);
    }
    faces.extend_from_slice(&cavity);
    (positions, faces, cavity)
}

/// The thick cylinder of radii `a` and `b` in plane strain (every vertex held along z; its
/// length a quarter of its width) under the dead load `nominal` (Pa of rest area) on its
/// cavity, held on the planes x = 0 and y = 0 along their normals: the mean inner stretch.
/// An open selection's pressure is dead (on the rest surface); in this axisymmetric
/// deformation the faces keep their directions, so it is the follower pressure
/// `nominal / stretch`.
pub fn inflated_cylinder(
    tissue: &Tissue,
    (a, b): (f64, f64),
    resolution: usize,
    nominal: f64,
) -> Result<f64> {
    // The surface finer than the finest grid the suite runs (cells of b / 12): the dead load
    // sits on its vertices, and rings of vertices a cell or more apart load the grid in
    // lines, which a fine grid resolves as line loads (1.6 % too large a stretch at
    // resolution 24 with rings b / 4 apart).
    let (segments, layers, rings) = (128, 16, 8);
    let (positions, faces, cavity) = hollow_cylinder((a, b, 0.5 * b), (segments, layers, rings));
    let fixed: Vec<[bool; 3]> =
        positions.iter().map(|x| [x[0].abs() < 1e-9 * b, x[1].abs() < 1e-9 * b, true]).collect();
    let options = FemOptions { resolution, ..FemOptions::default() };
    let pressure = Pressure { value: nominal, faces: cavity.clone() };
    let mut body =
        HyperBody::from_surface(&positions, &faces, tissue, &fixed, &options)?.with_pressures(&[pressure])?;
    let sol = body.solve(&Loads::default(), &[])?;
    Ok(mean_stretch(&positions, &sol.surface_displacements, &cavity, 2))
}

/// Cook's membrane in plane strain: the tapered panel with corners (0, 0), (48, 44),
/// (48, 60) and (0, 44) mm, `thickness` (m) deep along z with every vertex held along z,
/// clamped on x = 0, under a dead shear traction `traction` (Pa, along +y) on x = 48 mm:
/// the mean vertical displacement (m) of the corner (48, 60) mm. The surface is a box's
/// lattice (`cells` squares along the panel's two sides, `layers` through the thickness)
/// mapped bilinearly onto the panel.
pub fn cooks_membrane(
    tissue: &Tissue,
    resolution: usize,
    (thickness, traction): (f64, f64),
    (cells, layers): (usize, usize),
) -> Result<f64> {
    let (lattice, triangles) = box_surface([0.0; 3], [cells, cells, layers], 1.0);
    let (n, m) = (cells as f64, layers as f64);
    let positions: Vec<Vec3> = lattice
        .iter()
        .map(|p| {
            let (s, t) = (p[0] / n, p[1] / n);
            [0.048 * s, 0.044 * (s + t) - 0.028 * s * t, thickness * p[2] / m]
        })
        .collect();
    let on = |v: usize, axis: usize| lattice[v][axis] == n;
    let fixed: Vec<[bool; 3]> = lattice.iter().map(|p| [p[0] == 0.0, p[0] == 0.0, true]).collect();
    // The right edge's lattice is uniform (16 mm by the thickness): each vertex carries its
    // share of the area, halved on each side it lies on.
    let share = |v: usize| {
        let half = |c: f64, top: f64| if c == 0.0 || c == top { 0.5 } else { 1.0 };
        half(lattice[v][1], n) * half(lattice[v][2], m)
    };
    let loaded: Vec<usize> = (0..lattice.len()).filter(|&v| on(v, 0)).collect();
    let total_share: f64 = loaded.iter().map(|&v| share(v)).sum();
    let force = traction * 0.016 * thickness;
    let point_forces = loaded.iter().map(|&v| (v, [0.0, force * share(v) / total_share, 0.0])).collect();
    let options = FemOptions { resolution, ..FemOptions::default() };
    let mut body = HyperBody::from_surface(&positions, &triangles, tissue, &fixed, &options)?;
    let sol = body.solve(&Loads { point_forces, ..Loads::default() }, &[])?;
    let corner: Vec<usize> = (0..lattice.len()).filter(|&v| on(v, 0) && on(v, 1)).collect();
    Ok(corner.iter().map(|&v| sol.surface_displacements[v][1]).sum::<f64>() / corner.len() as f64)
}

/// A sphere of radius `r` (an icosphere of `level`) between two frictionless plates normal
/// to y that each approach its centre by `depth` (m), held on its symmetry planes: the force
/// on the upper plate (N).
pub fn pressed_sphere(tissue: &Tissue, (r, level): (f64, u32), resolution: usize, depth: f64) -> Result<f64> {
    let mesh = icosphere(level, r);
    let fixed = symmetry_planes(mesh.positions(), r);
    let options = FemOptions { resolution, ..FemOptions::default() };
    let mut body = HyperBody::from_surface(mesh.positions(), mesh.triangles(), tissue, &fixed, &options)?;
    let plate = |side: f64| RigidPlate {
        start: [0.0, side * r, 0.0],
        end: [0.0, side * (r - depth), 0.0],
        normal: [0.0, -side, 0.0],
        force: None,
    };
    let sol = body.solve(&Loads::default(), &[plate(1.0), plate(-1.0)])?;
    Ok(sol.plate_forces[0])
}

/// A cantilever of length 1 m and square section `1 / slenderness` (m), clamped at x = 0,
/// under a dead load along -z on its free end of `alpha E I / L^2` (spread evenly over the
/// end face's vertices): the tip's mean deflection along -z and its mean shortening along
/// x (m).
pub fn bent_cantilever(
    tissue: &Tissue,
    slenderness: usize,
    resolution: usize,
    alpha: f64,
) -> Result<[f64; 2]> {
    let across = (resolution / slenderness).max(1);
    let h = 1.0 / resolution as f64;
    let (pos, tris) = box_surface([0.0; 3], [resolution, across, across], h);
    let b = across as f64 * h;
    let fixed: Vec<[bool; 3]> = pos.iter().map(|x| [x[0] == 0.0; 3]).collect();
    let tip: Vec<usize> = (0..pos.len()).filter(|&v| (pos[v][0] - 1.0).abs() < 1e-12).collect();
    let load = alpha * tissue.young() * b.powi(4) / 12.0;
    let share = load / tip.len() as f64;
    let loads =
        Loads { point_forces: tip.iter().map(|&v| (v, [0.0, 0.0, -share])).collect(), ..Loads::default() };
    let options = FemOptions { resolution, ..FemOptions::default() };
    let mut body = HyperBody::from_surface(&pos, &tris, tissue, &fixed, &options)?;
    let sol = body.solve(&loads, &[])?;
    let mean =
        |axis: usize| tip.iter().map(|&v| sol.surface_displacements[v][axis]).sum::<f64>() / tip.len() as f64;
    Ok([-mean(2), -mean(0)])
}
