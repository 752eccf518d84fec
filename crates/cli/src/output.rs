//! Output files: deformed OBJ, legacy VTK, XML VTK PolyData, report JSON and a PNG render,
//! written to a temporary directory and moved into place only when everything succeeded.

use std::io::Write;
use std::path::{Path, PathBuf};

use fibfluid::geometry::Vec3;
use fibfluid::sim::fem_run::{FemReport, FemRun};
use fibfluid::{Model, Report, Shape, Simulation};

use crate::plates_png::{PlateCurve, PlateScene};
use crate::{Error, Result};

/// Names of the files a run writes.
pub const OUTPUT_FILES: [&str; 5] =
    ["deformed.obj", "deformed.vtk", crate::vtp::SURFACE_FILE, "report.json", "render.png"];

/// The force–thickness chart a run with plates writes beside [`OUTPUT_FILES`].
pub const COMPRESSION_FILE: &str = "compression.png";

/// Writes legacy VTK polydata (ASCII) with the displacement vector and its magnitude as
/// point data; ParaView opens it directly.
pub fn write_vtk(
    out: &mut impl Write,
    title: &str,
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    displacement: &[Vec3],
) -> std::io::Result<()> {
    writeln!(out, "# vtk DataFile Version 3.0")?;
    writeln!(out, "{}", title.replace('\n', " "))?;
    writeln!(out, "ASCII")?;
    writeln!(out, "DATASET POLYDATA")?;
    writeln!(out, "POINTS {} double", positions.len())?;
    for p in positions {
        writeln!(out, "{:?} {:?} {:?}", p[0], p[1], p[2])?;
    }
    writeln!(out, "POLYGONS {} {}", triangles.len(), 4 * triangles.len())?;
    for t in triangles {
        writeln!(out, "3 {} {} {}", t[0], t[1], t[2])?;
    }
    writeln!(out, "POINT_DATA {}", positions.len())?;
    writeln!(out, "VECTORS displacement double")?;
    for d in displacement {
        writeln!(out, "{:?} {:?} {:?}", d[0], d[1], d[2])?;
    }
    writeln!(out, "SCALARS displacement_magnitude double 1")?;
    writeln!(out, "LOOKUP_TABLE default")?;
    for d in displacement {
        writeln!(out, "{:?}", (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt())?;
    }
    Ok(())
}

/// Writes the kept fibers as VTK line polydata (the paper's Fig. 2 and 7).
pub fn write_fibers_vtk(
    out: &mut impl Write,
    positions: &[Vec3],
    fibers: &fibfluid::geometry::FiberSet,
) -> std::io::Result<()> {
    writeln!(out, "# vtk DataFile Version 3.0")?;
    writeln!(out, "fibfluid kept fibers")?;
    writeln!(out, "ASCII")?;
    writeln!(out, "DATASET POLYDATA")?;
    writeln!(out, "POINTS {} double", positions.len())?;
    for p in positions {
        writeln!(out, "{:?} {:?} {:?}", p[0], p[1], p[2])?;
    }
    writeln!(out, "LINES {} {}", fibers.kept(), 3 * fibers.kept())?;
    for (i, j) in fibers.pairs() {
        writeln!(out, "2 {i} {j}")?;
    }
    Ok(())
}

/// Surface triangles for output (a polygon is drawn as a fan, for pictures only).
fn triangles_of(sim: &Simulation) -> Vec<[u32; 3]> {
    match &sim.model().shape {
        Shape::Surface(m) => m.mesh.triangles().to_vec(),
        Shape::Polygon(p) => (1..p.n_vertices() as u32 - 1).map(|k| [0, k, k + 1]).collect(),
    }
}

/// Renders the rest and deformed shapes side by side, colored by displacement magnitude
/// (with plates: the plates' outlines at rest and at the end, the deformed shape colored
/// by contact pressure, so the contact patches show).
pub fn render_png(sim: &Simulation) -> Result<Vec<u8>> {
    if !sim.model().plates.is_empty() {
        return PlateScene::of_simulation(sim, triangles_of(sim)).render();
    }
    let title = format!("deformed ({} steps, {})", sim.model().load.steps, sim.model().solver.mode);
    render_rest_and_deformed(&SurfaceResult::of_simulation(sim), &title)
}

/// The rest and deformed shapes side by side, the deformed one colored by `|u|` in the
/// mesh's unit.
fn render_rest_and_deformed(surface: &SurfaceResult<'_>, title: &str) -> Result<Vec<u8>> {
    let (rest, now) = (surface.rest, surface.positions);
    let to_unit = 1.0 / surface.model.unit.metres();
    let mag: Vec<f64> =
        now.iter().zip(rest).map(|(p, r)| to_unit * fibfluid::geometry::vec3::dist(*p, *r)).collect();
    let zero = vec![0.0; mag.len()];
    let label = format!("|u| ({})", surface.model.unit);
    let opts = fibfluid::render::ViewOptions { scalar_label: label, ..Default::default() };
    let tris = &surface.triangles;
    let panels = [
        fibfluid::render::Surface { positions: rest, triangles: tris, scalar: &zero, title: "rest".into() },
        fibfluid::render::Surface { positions: now, triangles: tris, scalar: &mag, title: title.to_string() },
    ];
    Ok(fibfluid::render::render_surfaces(&panels, None, &opts)?)
}

/// Force (N) against thickness (the mesh's unit) for each plate of an FFM run
/// (`compression.png`).
pub fn compression_png(sim: &Simulation) -> Result<Vec<u8>> {
    let curves: Vec<PlateCurve> = sim
        .plate_records()
        .iter()
        .map(|r| PlateCurve { gap: r.gap.clone(), force: r.force.clone() })
        .collect();
    crate::plates_png::compression_png(sim.model(), &curves)
}

/// Whether a finite-element run draws its plates: a static run with plates (a timed run's
/// plate forces are in `series.csv`).
pub fn fem_draws_plates(model: &Model) -> bool {
    !model.plates.is_empty() && model.fem.time.is_none()
}

/// A deformed surface to write: the model (its mesh, name and unit), rest and deformed
/// positions in metres, the mesh's triangles.
pub struct SurfaceResult<'a> {
    /// The model.
    pub model: &'a Model,
    /// Rest positions (m).
    pub rest: &'a [Vec3],
    /// Deformed positions (m).
    pub positions: &'a [Vec3],
    /// Triangles (a polygon: a fan, for pictures only).
    pub triangles: Vec<[u32; 3]>,
}

impl<'a> SurfaceResult<'a> {
    /// The surface of an FFM simulation.
    pub fn of_simulation(sim: &'a Simulation) -> Self {
        Self {
            model: sim.model(),
            rest: sim.rest_positions(),
            positions: sim.positions(),
            triangles: triangles_of(sim),
        }
    }

    /// The surface of a finite-element run.
    pub fn of_fem(run: &'a FemRun) -> Self {
        let triangles = match &run.model.shape {
            Shape::Surface(m) => m.mesh.triangles().to_vec(),
            Shape::Polygon(_) => Vec::new(),
        };
        Self { model: &run.model, rest: &run.rest, positions: &run.positions, triangles }
    }

    /// Positions in the mesh file's vertex order and unit, and the triangles in file
    /// indices.
    fn in_file_terms(&self, positions: &[Vec3]) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let to_unit = 1.0 / self.model.unit.metres();
        let (p, t) = match &self.model.shape {
            Shape::Surface(m) => (m.positions_in_file_order(positions), m.triangles_in_file_order()),
            Shape::Polygon(_) => (positions.to_vec(), self.triangles.clone()),
        };
        (p.into_iter().map(|x| x.map(|c| c * to_unit)).collect(), t)
    }
}

/// Writes every output of an FFM run into `dir` (see [`write_files_atomically`]).
pub fn write_outputs(dir: &Path, sim: &Simulation, report: &Report) -> Result<Vec<PathBuf>> {
    let json = serde_json::to_string_pretty(report)? + "\n";
    let png = render_png(sim)?;
    let extra =
        if sim.model().plates.is_empty() { vec![] } else { vec![(COMPRESSION_FILE, compression_png(sim)?)] };
    write_surface(dir, &SurfaceResult::of_simulation(sim), json, png, extra)
}

/// Writes every output of a finite-element run into `dir`, the cells' volume file
/// ([`crate::vtu::VOLUME_FILE`]) included.
pub fn write_fem_outputs(dir: &Path, run: &FemRun, report: &FemReport) -> Result<Vec<PathBuf>> {
    let surface = SurfaceResult::of_fem(run);
    let json = serde_json::to_string_pretty(report)? + "\n";
    let mut vtu = Vec::new();
    crate::vtu::write_vtu(&mut vtu, run)
        .map_err(|source| Error::Io { path: dir.join(crate::vtu::VOLUME_FILE), source })?;
    let mut extra = vec![(crate::vtu::VOLUME_FILE, vtu)];
    let png = if fem_draws_plates(&run.model) {
        let curves = crate::plates_png::fem_curves(run);
        extra.push((COMPRESSION_FILE, crate::plates_png::compression_png(&run.model, &curves)?));
        PlateScene::of_fem(run, surface.triangles.clone()).render()?
    } else {
        let title = format!("deformed (fem, resolution {})", run.stats.resolution);
        render_rest_and_deformed(&surface, &title)?
    };
    if let Some(series) = crate::series::series_csv(run) {
        extra.push((crate::series::SERIES_FILE, series));
    }
    write_surface(dir, &surface, json, png, extra)
}

/// `deformed.obj`, `deformed.vtk` and `deformed.vtp` (file order, the mesh's unit),
/// `report.json`, `render.png` and any extra files, all or nothing.
fn write_surface(
    dir: &Path,
    surface: &SurfaceResult<'_>,
    json: String,
    png: Vec<u8>,
    extra: Vec<(&str, Vec<u8>)>,
) -> Result<Vec<PathBuf>> {
    let (positions, triangles) = surface.in_file_terms(surface.positions);
    let (rest, _) = surface.in_file_terms(surface.rest);
    let disp: Vec<Vec3> =
        positions.iter().zip(&rest).map(|(p, r)| [p[0] - r[0], p[1] - r[1], p[2] - r[2]]).collect();
    let io = |name: &str| {
        let path = dir.join(name);
        move |source| Error::Io { path, source }
    };
    let [obj_name, vtk_name, vtp_name, json_name, png_name] = OUTPUT_FILES;
    let mut obj = Vec::new();
    fibfluid::geometry::write_obj_to(&mut obj, &positions, &triangles).map_err(io(obj_name))?;
    let mut vtk = Vec::new();
    let title = format!("fibfluid {} ({})", surface.model.name, surface.model.unit);
    write_vtk(&mut vtk, &title, &positions, &triangles, &disp).map_err(io(vtk_name))?;
    let mut vtp = Vec::new();
    crate::vtp::write_vtp(&mut vtp, &title, &positions, &triangles, &disp).map_err(io(vtp_name))?;
    let mut files = vec![
        (obj_name, obj),
        (vtk_name, vtk),
        (vtp_name, vtp),
        (json_name, json.into_bytes()),
        (png_name, png),
    ];
    files.extend(extra);
    write_files_atomically(dir, &files)
}

/// Writes named files into `dir` all or nothing: they go to a fresh temporary directory
/// beside `dir` first and are moved in only when every one was written, so a failure
/// leaves `dir` (and any file the user had there) untouched. Files of the same names are
/// replaced; other files in `dir` are left alone.
///
/// Every error names `dir` as the caller gave it (or the output file in it), never the
/// temporary directory, which the user did not ask for.
pub fn write_files_atomically(dir: &Path, files: &[(&str, Vec<u8>)]) -> Result<Vec<PathBuf>> {
    // Errors name what the user gave (`dir` and the files in it), never the temporary
    // directory, which is an implementation detail: `path` is what the error names; `doing`
    // says what failed (and where, when that was the temporary directory or a parent).
    let io_at = |path: &Path, doing: String| {
        let path = path.to_path_buf();
        move |source: std::io::Error| Error::Io {
            path,
            source: std::io::Error::new(
                source.kind(),
                format!("cannot write the outputs here: {doing}: {source}"),
            ),
        }
    };
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| Error::Io { path, source }
    };
    let parent = parent_of(dir);
    let names: Vec<&str> = files.iter().map(|(name, _)| *name).collect();
    check_output_dir(dir, &names)?;
    std::fs::create_dir_all(&parent)
        .map_err(io_at(dir, format!("creating its parent directory {}", parent.display())))?;
    let tmp = parent.join(format!(".fibfluid-tmp-{}-{}", std::process::id(), nanos()));
    std::fs::create_dir(&tmp)
        .map_err(io_at(dir, format!("creating a temporary directory in {}", parent.display())))?;
    let result = (|| -> Result<()> {
        for (name, bytes) in files {
            let (p, shown) = (tmp.join(name), dir.join(name));
            let mut f = std::fs::File::create(&p).map_err(io(&shown))?;
            f.write_all(bytes).map_err(io(&shown))?;
            f.sync_all().map_err(io(&shown))?;
        }
        std::fs::create_dir_all(dir).map_err(io(dir))
    })();
    if let Err(e) = result {
        let _ = std::fs::remove_dir_all(&tmp);
        return Err(e);
    }
    let mut written = Vec::new();
    for (name, _) in files {
        let (from, to) = (tmp.join(name), dir.join(name));
        if let Err(source) = std::fs::rename(&from, &to) {
            let _ = std::fs::remove_dir_all(&tmp);
            return Err(Error::Io { path: to, source });
        }
        written.push(to);
    }
    let _ = std::fs::remove_dir_all(&tmp);
    Ok(written)
}

/// The directory the temporary directory of [`write_files_atomically`] goes in.
pub(crate) fn parent_of(dir: &Path) -> PathBuf {
    match dir.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// Checks, before any work, that the files `names` can be written into `dir` by
/// [`write_files_atomically`]: `dir` is a directory or does not exist yet, no output name is
/// taken by a directory, and both `dir` (when it exists) and the directory the temporary
/// directory goes in (or its nearest existing ancestor) take new entries. Writes nothing
/// that stays.
pub fn check_output_dir(dir: &Path, names: &[&str]) -> Result<()> {
    if dir.exists() && !dir.is_dir() {
        return Err(Error::OutputBlocked {
            path: dir.to_path_buf(),
            problem: "exists and is not a directory",
        });
    }
    // A directory in the way of one output would stop the moves half-way: refuse up front.
    if let Some(blocked) = names.iter().map(|name| dir.join(name)).find(|p| p.is_dir()) {
        return Err(Error::OutputBlocked {
            path: blocked,
            problem: "is a directory, where an output file would go (nothing was written)",
        });
    }
    let mut places = vec![];
    if dir.is_dir() {
        places.push(dir.to_path_buf());
    }
    let mut above = parent_of(dir);
    while !above.exists() {
        match above.parent() {
            Some(p) if !p.as_os_str().is_empty() => above = p.to_path_buf(),
            _ => above = PathBuf::from("."),
        }
    }
    if above.is_dir() && !places.contains(&above) {
        places.push(above);
    }
    for place in places {
        let probe = place.join(format!(".fibfluid-probe-{}-{}", std::process::id(), nanos()));
        match std::fs::create_dir(&probe) {
            Ok(()) => {
                let _ = std::fs::remove_dir(&probe);
            }
            Err(source) => {
                return Err(Error::Io {
                    path: dir.to_path_buf(),
                    source: std::io::Error::new(
                        source.kind(),
                        format!(
                            "cannot write the outputs here: {} takes no new files: {source}",
                            place.display()
                        ),
                    ),
                });
            }
        }
    }
    Ok(())
}

pub(crate) fn nanos() -> u128 {
    std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map(|d| d.as_nanos()).unwrap_or(0)
}
