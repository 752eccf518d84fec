//! From the file's tables to the engine's validated values.

use std::path::Path;

use fibfluid_assembly::{
    AssemblyError, Constraints, DEFAULT_PENALTY, Material, MaterialParameter, PAPER_KERNEL_EXPONENT,
    Selector, StiffnessLaw,
};
use fibfluid_geometry::{MeshFile, Polygon, ReadOptions, load_mesh_with};
use fibfluid_sim::contact::{Plate, PlateProblem, check_plates};
use fibfluid_sim::guards::Guards;
use fibfluid_sim::{
    FemSettings, FfmSettings, FiberModel, ForceTiming, LengthUnit, MAX_STEPS, Method, Model,
    PLATE_REST_TOLERANCE, PointForce, Shape, SolverOptions, Tissue,
};

use crate::error::SceneProblem;
use crate::invalid::{Invalid, choice, invalid, range, unkeyed};
use crate::spec::*;

fn axis_index(s: &str, key: &str) -> Result<usize, Invalid> {
    match s {
        "x" => Ok(0),
        "y" => Ok(1),
        "z" => Ok(2),
        other => Err(invalid(key, SceneProblem::NotAnAxis { given: other.to_string() })),
    }
}

/// The scene's values, built from its tables; `dir` resolves the mesh path. `mesh`, when
/// given, stands for the file's `[mesh]` (see `Scene::load_with_mesh`); it is taken as
/// already in metres.
pub(crate) fn build(
    mut spec: SceneToml,
    dir: &Path,
    name: String,
    mesh: Option<MeshFile>,
) -> Result<Model, Invalid> {
    let unit =
        spec.mesh.as_ref().map(|m| choice("[mesh].unit", m.unit.clone(), LengthUnit::Metre)).transpose()?;
    let unit = unit.unwrap_or_default();
    let mesh_scale = spec.mesh.as_ref().and_then(|m| m.scale).unwrap_or(1.0);
    let image = spec.mesh.as_ref().and_then(|m| m.image.as_ref()).map(|i| dir.join(i));
    let (shape, label_image) = match mesh {
        None => shape(spec.mesh, spec.polygon, dir, unit)?,
        Some(_) if spec.polygon.is_some() => {
            return Err(invalid(
                "[polygon]",
                SceneProblem::Conflict(
                    "the body is a polygon: only a [mesh] can be replaced by another mesh",
                ),
            ));
        }
        Some(m) => (Shape::Surface(Box::new(m)), None),
    };
    let axes = if matches!(shape, Shape::Polygon(_)) { 2 } else { 3 };
    let solver = solver(spec.solver)?;
    let (tissue, auto_model) = match spec.tissue.map(crate::tissue_table::tissue).transpose()? {
        Some((t, auto)) => (Some(t), auto),
        None => (None, false),
    };
    let mut fem = fem_settings(spec.fem)?;
    fem.auto_model = auto_model;
    fem.regions = crate::regions::regions(
        spec.region,
        dir,
        (unit, mesh_scale),
        image.map(|p| (p, label_image)),
        tissue.as_ref(),
    )?;
    let (material, ffm) =
        ffm_material(spec.material, spec.ffm, spec.fluid, tissue.as_ref(), solver.method, axes)?;
    let curve = spec.load.as_mut().and_then(|l| l.curve.take());
    fem.time = crate::time_table::timed_run(spec.time, curve)?;
    if fem.time.is_some() && fem.tolerance.is_some() {
        let problem = "a timed run ([time]) runs at [fem] resolution: remove [fem] tolerance (or [time])";
        return Err(invalid("[fem].tolerance", SceneProblem::Conflict(problem)));
    }
    let (steps, tolerance) = load(spec.load)?;
    let guards = guards(spec.guards)?;
    let gravity = spec.gravity.map(|g| g.acceleration).unwrap_or([0.0; 3]);
    if let Some(c) = gravity.iter().find(|c| !c.is_finite()) {
        return Err(range("[gravity].acceleration", "finite", c));
    }
    let fit_spec = spec.fit.take();
    let vertices = VertexMap::of(&shape, unit);
    let constraints = constraints(&spec.fix, &vertices, axes)?;
    let forces = forces(&spec.force, &vertices)?;
    for c in 0..axes {
        if constraints.count(c) == 0 {
            return Err(Invalid {
                key: Some("[[fix]]".into()),
                problem: SceneProblem::Unconstrained { axis: fibfluid_geometry::AXES[c] },
            });
        }
    }
    let plates = plates(&spec.plate, &vertices, fem.time.is_some())?;
    fem.grasps = grasps(&spec.grasp, &vertices, &constraints)?;
    let is_fem = solver.method == fibfluid_sim::Method::Fem;
    fem.pressures = crate::pressure_table::pressures(&spec.pressure, &shape, unit.metres(), is_fem)?;
    let mut model = Model::new(name, shape, material);
    model.constraints = constraints;
    model.load.gravity = gravity;
    model.load.forces = forces;
    model.load.steps = steps;
    model.load.tolerance = tolerance;
    model.guards = guards;
    model.plates = plates;
    model.solver = solver;
    model.tissue = tissue;
    model.fem = fem;
    model.ffm = ffm;
    model.unit = unit;
    model.fem.fit = crate::fit_table::fit(fit_spec, dir, &model, mesh_scale * unit.metres())?;
    Ok(model)
}

/// `[fem]`.
fn fem_settings(f: Option<FemToml>) -> Result<FemSettings, Invalid> {
    let mut s = FemSettings::default();
    let Some(f) = f else { return Ok(s) };
    if let Some(r) = f.resolution {
        if !(1..=fibfluid_fem::MAX_RESOLUTION as i64).contains(&r) {
            return Err(range("[fem].resolution", "between 1 and 256 (cells along the longest side)", r));
        }
        s.resolution = r as usize;
    }
    s.solver = choice("[fem].solver", f.solver, s.solver)?;
    if let Some(t) = f.tolerance {
        if !(t.is_finite() && t > 0.0 && t < 1.0) {
            return Err(range(
                "[fem].tolerance",
                "between 0 and 1 (the estimated relative error of the surface's displacement)",
                t,
            ));
        }
        s.tolerance = Some(t);
    }
    Ok(s)
}

/// The body: a mesh file (converted from its unit to metres) or a polygon.
/// The body, and the label image it was extracted from (`[mesh] image`), kept for the
/// scene's `label` regions.
fn shape(
    mesh: Option<MeshToml>,
    polygon: Option<PolygonToml>,
    dir: &Path,
    unit: LengthUnit,
) -> Result<(Shape, Option<fibfluid_geometry::LabelImage>), Invalid> {
    let shape = match (mesh, polygon) {
        (Some(m), None) if m.image.is_some() => return image_shape(m, dir).map(|(s, i)| (s, Some(i))),
        (Some(m), None) => {
            let Some(path) = m.path.clone() else {
                return Err(unkeyed(SceneProblem::Conflict("[mesh] needs `path` (a mesh file) or `image`")));
            };
            if m.label.is_some() || m.vertices.is_some() || m.smooth.is_some() {
                return Err(unkeyed(SceneProblem::Conflict(
                    "[mesh] `label`, `vertices` and `smooth` go with `image`, not `path`",
                )));
            }
            let mesh_path = dir.join(&path);
            if !mesh_path.exists() {
                return Err(invalid(
                    "[mesh].path",
                    SceneProblem::MeshNotFound { given: path, resolved: mesh_path },
                ));
            }
            if let Some(s) = m.scale
                && !(s.is_finite() && s > 0.0)
            {
                return Err(range("[mesh].scale", "positive", s));
            }
            // Scaled before validation: coordinates too large or small for f64 are checked
            // in the units the scene uses (metres inside).
            let scale = Some(m.scale.unwrap_or(1.0) * unit.metres()).filter(|s| *s != 1.0);
            let file = load_mesh_with(&mesh_path, &ReadOptions { scale, ..Default::default() })
                .map_err(|e| invalid("[mesh].path", SceneProblem::Mesh(e)))?;
            Shape::Surface(Box::new(file))
        }
        (None, Some(p)) => Shape::Polygon(Polygon::new(p.points).ok_or_else(|| {
            invalid("[polygon].points", SceneProblem::Conflict("at least 3 finite points are needed"))
        })?),
        (Some(_), Some(_)) => {
            return Err(unkeyed(SceneProblem::Conflict("give either [mesh] or [polygon], not both")));
        }
        (None, None) => return Err(unkeyed(SceneProblem::Conflict("missing [mesh] (or [polygon]) table"))),
    };
    Ok((shape, None))
}

/// The body from a label image: the surface of `label` (default: every non-zero label),
/// decimated to at most `vertices`, in metres (the image's physical spacing).
fn image_shape(m: MeshToml, dir: &Path) -> Result<(Shape, fibfluid_geometry::LabelImage), Invalid> {
    use fibfluid_geometry::{LabelSelection, MeshFile, SurfaceOptions, extract_surface, read_nifti};
    if m.path.is_some() {
        return Err(unkeyed(SceneProblem::Conflict("give either [mesh].path or [mesh].image, not both")));
    }
    if m.scale.is_some() || m.unit.as_deref().is_some_and(|u| u != "m") {
        return Err(unkeyed(SceneProblem::Conflict(
            "[mesh].image is in metres (its spacing): `scale` and `unit` other than \"m\" are not used with it",
        )));
    }
    let given = m.image.unwrap_or_default();
    let path = dir.join(&given);
    if !path.exists() {
        return Err(invalid("[mesh].image", SceneProblem::MeshNotFound { given, resolved: path }));
    }
    let selection = match m.label {
        None => LabelSelection::NonZero,
        Some(l) if (1..=u32::MAX as i64).contains(&l) => LabelSelection::Label(l as u32),
        Some(l) => return Err(range("[mesh].label", "a label between 1 and 4294967295", l)),
    };
    let target_vertices = match m.vertices {
        None => None,
        Some(v) if v >= 4 => Some(v as usize),
        Some(v) => return Err(range("[mesh].vertices", "at least 4", v)),
    };
    let image = read_nifti(&path).map_err(|e| invalid("[mesh].image", SceneProblem::Image(e)))?;
    let opts = SurfaceOptions {
        selection,
        target_vertices,
        smooth: m.smooth.unwrap_or(false),
        fill_cavities: false,
    };
    let surface = extract_surface(&image, &opts)
        .map_err(|source| invalid("[mesh].image", SceneProblem::Surface { path: path.clone(), source }))?;
    let file = MeshFile::from_mesh(&path, surface.mesh).map_err(|source| {
        let source = fibfluid_geometry::SurfaceError::Mesh { selection, source };
        invalid("[mesh].image", SceneProblem::Surface { path, source })
    })?;
    Ok((Shape::Surface(Box::new(file)), image))
}

/// The fiber parameters as given, and where: the table and the fiber modulus's key, for
/// messages.
struct Fibers {
    /// `[ffm]`, `[material]`, or `[tissue]` for the placeholder to be calibrated.
    table: &'static str,
    /// `fiber_modulus`, or its older name `young`.
    modulus_key: &'static str,
    fiber_modulus: FiberModulusToml,
    surface_tension: f64,
    stiffening: Option<f64>,
}

impl Fibers {
    /// `[material]` as written (the older table: its fiber modulus is `young`).
    fn of_material(m: MaterialToml) -> Self {
        Fibers {
            table: "[material]",
            modulus_key: "young",
            fiber_modulus: m.fiber_modulus,
            surface_tension: m.surface_tension,
            stiffening: m.stiffening,
        }
    }

    /// `[ffm]`'s fibers when it gives a fiber modulus, as `fiber_modulus` or by its older
    /// name `young` (not both).
    fn of_ffm(f: &FfmToml) -> Result<Option<Self>, Invalid> {
        let (fiber_modulus, modulus_key) = match (f.fiber_modulus, f.young) {
            (Some(_), Some(_)) => {
                return Err(invalid(
                    "[ffm].fiber_modulus",
                    SceneProblem::Conflict(
                        "give the fiber modulus as `fiber_modulus` or by its older name `young`, not both",
                    ),
                ));
            }
            (Some(m), None) => (m, "fiber_modulus"),
            (None, Some(m)) => (m, "young"),
            (None, None) => return Ok(None),
        };
        Ok(Some(Fibers {
            table: "[ffm]",
            modulus_key,
            fiber_modulus,
            surface_tension: f.surface_tension.unwrap_or(0.0),
            stiffening: f.stiffening,
        }))
    }

    /// `table.key`, as messages name it.
    fn key(&self, key: &str) -> String {
        format!("{}.{key}", self.table)
    }
}

/// FFM's material and fiber settings from `[material]` (the older name) or `[ffm]`, and
/// `[fluid]`. A scene with only `[tissue]` gets the tissue's modulus as a placeholder to be
/// calibrated against the FEM before an FFM run (its density too when `[fluid]` is absent).
/// Only the error of a scene with neither depends on `[solver] method` (`method`): a method
/// chosen later (a command-line flag, a binding's argument) runs the same FFM as the key.
fn ffm_material(
    old: Option<MaterialToml>,
    ffm: Option<FfmToml>,
    fluid: Option<FluidToml>,
    tissue: Option<&Tissue>,
    method: Method,
    axes: usize,
) -> Result<(Material, FfmSettings), Invalid> {
    let fibers = choice("[ffm].fibers", ffm.as_ref().and_then(|f| f.fibers.clone()), FiberModel::Paper)?;
    let mut settings = FfmSettings { fibers, calibrate: false };
    let kernel = ffm.as_ref().and_then(|f| f.kernel_exponent).unwrap_or(PAPER_KERNEL_EXPONENT);
    let kernel = checked("[ffm].kernel_exponent", MaterialParameter::KernelExponent, kernel)?;
    let with_kernel = |mut m: Material| {
        m.set_kernel_exponent(kernel).expect("checked above");
        m
    };
    let new = ffm.as_ref().map(Fibers::of_ffm).transpose()?.flatten();
    let given = match (old, new) {
        (Some(_), Some(new)) => {
            return Err(invalid(
                new.key(new.modulus_key),
                SceneProblem::Conflict(
                    "give the fiber parameters in [ffm] or in the older [material], not both",
                ),
            ));
        }
        (old, new) => old.map(Fibers::of_material).or(new),
    };
    if let Some(f) = given {
        return Ok((with_kernel(material(f, fluid, axes)?), settings));
    }
    let Some(t) = tissue else {
        return Err(unkeyed(SceneProblem::Conflict(if method == Method::Fem {
            "method fem needs a [tissue] table (young in Pa, poisson, density in kg/m^3)"
        } else {
            "missing fiber parameters: give [ffm] (fiber_modulus, surface_tension) or a [tissue] table to calibrate them from"
        })));
    };
    // No fiber modulus: FFM's is calibrated on the body against the FEM before an FFM run
    // (whatever chose the method), with the surface fibers of `[ffm] surface_tension` when
    // given (they hold the vertices that culling leaves without a fiber); the FEM itself
    // does not use them.
    settings.calibrate = true;
    let tension = ffm.as_ref().and_then(|f| f.surface_tension).unwrap_or(0.0);
    let tension = checked("[ffm].surface_tension", MaterialParameter::SurfaceTension, tension)?;
    // The calibration fits the small-strain modulus (paper mode); the scene's stiffening
    // then acts on it in nonlinear mode, as with a modulus given.
    let stiffening = ffm.as_ref().and_then(|f| f.stiffening);
    let stiffening =
        stiffening.map(|c| checked("[ffm].stiffening", MaterialParameter::Stiffening, c)).transpose()?;
    let density = match &fluid {
        Some(f) => f.density,
        None => t.density(),
    };
    let placeholder = Fibers {
        table: "[tissue]",
        modulus_key: "young",
        fiber_modulus: FiberModulusToml::One(t.young()),
        surface_tension: tension,
        stiffening,
    };
    Ok((with_kernel(material(placeholder, Some(FluidToml { density }), axes)?), settings))
}

/// The fibers (`[ffm]`, `[material]`) and `[fluid]`.
fn material(f: Fibers, fluid: Option<FluidToml>, axes: usize) -> Result<Material, Invalid> {
    let fiber_modulus = match f.fiber_modulus {
        FiberModulusToml::One(y) => [y; 3],
        FiberModulusToml::Three(y) => y,
    };
    let modulus_key = f.key(f.modulus_key);
    for (axis, y) in fiber_modulus.iter().enumerate().take(axes) {
        let parameter = MaterialParameter::FiberModulus { axis };
        if !parameter.accepts(*y) {
            let value = format!("{y} along {}", fibfluid_geometry::AXES[axis]);
            return Err(range(modulus_key, parameter.rule(), value));
        }
    }
    let gamma = checked(&f.key("surface_tension"), MaterialParameter::SurfaceTension, f.surface_tension)?;
    let law = match f.stiffening {
        None => StiffnessLaw::Linear,
        Some(c) => {
            StiffnessLaw::Quadratic { c: checked(&f.key("stiffening"), MaterialParameter::Stiffening, c)? }
        }
    };
    let density =
        checked("[fluid].density", MaterialParameter::Density, fluid.map(|f| f.density).unwrap_or(0.0))?;
    let mut material = Material::new(fiber_modulus, gamma, density).map_err(|e| match e {
        // A 2D body's unused z modulus must be valid too.
        AssemblyError::InvalidMaterial { parameter: MaterialParameter::FiberModulus { axis }, value } => {
            let value = format!("{value} along {}", fibfluid_geometry::AXES[axis]);
            range(modulus_key.clone(), MaterialParameter::FiberModulus { axis }.rule(), value)
        }
        other => invalid(f.table, SceneProblem::Constraint(other)),
    })?;
    material.set_law(law).expect("stiffening checked above");
    Ok(material)
}

/// `value` when `parameter` accepts it (the material's own rule), else a range error on `key`.
fn checked(key: &str, parameter: MaterialParameter, value: f64) -> Result<f64, Invalid> {
    parameter.check(value).map_err(|_| range(key, parameter.rule(), value))
}

/// `[load]`: the step count and the adaptive tolerance.
fn load(l: Option<LoadToml>) -> Result<(usize, Option<f64>), Invalid> {
    let (steps, tolerance) = l.map(|l| (l.steps, l.tolerance)).unwrap_or((None, None));
    let steps = steps.unwrap_or(if tolerance.is_some() { 4 } else { 1 });
    if !(1..=MAX_STEPS as i64).contains(&steps) {
        return Err(range("[load].steps", "between 1 and 1000000", steps));
    }
    if let Some(t) = tolerance
        && !(t.is_finite() && t > 0.0 && t < 1.0)
    {
        return Err(range("[load].tolerance", "between 0 and 1", t));
    }
    Ok((steps as usize, tolerance))
}

/// `[guards]`.
fn guards(g: Option<GuardsToml>) -> Result<Guards, Invalid> {
    let mut guards = Guards::default();
    let Some(g) = g else { return Ok(guards) };
    guards.on_failure = choice("[guards].on_failure", g.on_failure, guards.on_failure)?;
    for (key, value) in [("volume", g.volume), ("increment", g.increment), ("residual", g.residual)] {
        if let Some(v) = value
            && !(v.is_finite() && v > 0.0)
        {
            return Err(range(format!("[guards].{key}"), "positive", v));
        }
    }
    if let Some(k) = g.inverted
        && k < 0
    {
        return Err(range("[guards].inverted", ">= 0", k));
    }
    guards.volume = g.volume;
    guards.increment = g.increment;
    guards.residual = g.residual;
    guards.inverted = g.inverted.map(|k| k as usize);
    Ok(guards)
}

/// The body's vertices as the scene's keys name them: file order for a mesh.
struct VertexMap<'a> {
    n: usize,
    positions: Vec<fibfluid_geometry::Vec3>,
    file: Option<&'a fibfluid_geometry::MeshFile>,
    /// Metres per length unit of the scene: lengths written in the scene (selectors,
    /// plates) are in the mesh's unit, like the mesh's own numbers.
    metres: f64,
}

impl<'a> VertexMap<'a> {
    fn of(shape: &'a Shape, unit: LengthUnit) -> Self {
        let metres = unit.metres();
        match shape {
            Shape::Surface(m) => {
                Self { n: m.mesh.n_vertices(), positions: m.mesh.positions().to_vec(), file: Some(m), metres }
            }
            Shape::Polygon(p) => Self { n: p.n_vertices(), positions: p.positions_3d(), file: None, metres },
        }
    }

    /// The mesh index of file vertex `v` (checked: in range, used by a face).
    fn mesh_index(&self, v: i64, key: &str) -> Result<usize, Invalid> {
        let count = self.file.map(|f| f.file_vertex_count()).unwrap_or(self.n);
        if v < 0 || v as usize >= count {
            return Err(invalid(key, SceneProblem::VertexOutOfRange { vertex: v, count }));
        }
        match self.file {
            Some(f) => f
                .from_file_index(v as usize)
                .ok_or_else(|| invalid(key, SceneProblem::VertexUnused { vertex: v })),
            None => Ok(v as usize),
        }
    }

    /// The file index of mesh vertex `v`.
    fn file_index(&self, v: usize) -> usize {
        self.file.map(|f| f.to_file[v] as usize).unwrap_or(v)
    }
}

/// `[[fix]]` tables.
fn constraints(fixes: &[FixToml], vertices: &VertexMap<'_>, axes: usize) -> Result<Constraints, Invalid> {
    let mut constraints = Constraints::new(vertices.n);
    for (k, fix) in fixes.iter().enumerate() {
        let key = format!("[[fix]] #{}", k + 1);
        let dofs = fixed_axes(fix, &key, axes)?;
        let selector = selector(fix, &key, vertices)?;
        constraints
            .fix_selected(&selector, &vertices.positions, dofs)
            .map_err(|e| invalid(key.clone(), SceneProblem::Constraint(e)))?;
    }
    Ok(constraints)
}

/// The axes one `[[fix]]` table fixes (`dofs`, default all).
fn fixed_axes(fix: &FixToml, key: &str, axes: usize) -> Result<[bool; 3], Invalid> {
    let mut dofs = [false; 3];
    let Some(list) = &fix.dofs else {
        dofs[..axes].iter_mut().for_each(|d| *d = true);
        return Ok(dofs);
    };
    if list.is_empty() {
        return Err(invalid(format!("{key}.dofs"), SceneProblem::Conflict("empty list")));
    }
    for d in list {
        let c = axis_index(d, &format!("{key}.dofs"))?;
        if c >= axes {
            return Err(invalid(format!("{key}.dofs"), SceneProblem::Conflict("a 2D scene has no z axis")));
        }
        dofs[c] = true;
    }
    Ok(dofs)
}

/// Which vertices one `[[fix]]` table selects.
fn selector(fix: &FixToml, key: &str, vertices: &VertexMap<'_>) -> Result<Selector, Invalid> {
    let axis = fix.axis.as_deref().map(|a| axis_index(a, &format!("{key}.axis"))).transpose()?;
    let kinds = [
        fix.above.is_some(),
        fix.below.is_some(),
        fix.top.is_some(),
        fix.bottom.is_some(),
        fix.vertices.is_some(),
        fix.bbox.is_some(),
    ];
    if kinds.iter().filter(|k| **k).count() != 1 {
        return Err(invalid(
            key,
            SceneProblem::Conflict("give exactly one of above, below, top, bottom, vertices, box"),
        ));
    }
    let need_axis = || {
        axis.ok_or_else(|| {
            invalid(key, SceneProblem::Conflict("`axis` is required with above/below/top/bottom"))
        })
    };
    let within = |v: f64, name: &str| {
        if v.is_nan() || v < 0.0 { Err(range(format!("{key}.{name}"), ">= 0", v)) } else { Ok(v) }
    };
    let m = vertices.metres;
    Ok(if let Some(v) = fix.above {
        Selector::Above { axis: need_axis()?, value: v * m }
    } else if let Some(v) = fix.below {
        Selector::Below { axis: need_axis()?, value: v * m }
    } else if let Some(v) = fix.top {
        Selector::Top { axis: need_axis()?, within: within(v, "top")? * m }
    } else if let Some(v) = fix.bottom {
        Selector::Bottom { axis: need_axis()?, within: within(v, "bottom")? * m }
    } else if let Some(b) = fix.bbox {
        Selector::Box { min: b[0].map(|c| c * m), max: b[1].map(|c| c * m) }
    } else {
        let list = fix.vertices.as_deref().unwrap_or(&[]);
        let key = format!("{key}.vertices");
        Selector::Vertices(list.iter().map(|&v| vertices.mesh_index(v, &key)).collect::<Result<Vec<_>, _>>()?)
    })
}

/// `[[force]]` tables.
fn forces(forces: &[ForceToml], vertices: &VertexMap<'_>) -> Result<Vec<PointForce>, Invalid> {
    let mut out = Vec::with_capacity(forces.len());
    for (k, f) in forces.iter().enumerate() {
        let key = format!("[[force]] #{}", k + 1);
        let vertex = vertices.mesh_index(f.vertex, &format!("{key}.vertex"))?;
        if let Some(c) = f.value.iter().find(|c| !c.is_finite()) {
            return Err(range(format!("{key}.value"), "finite", c));
        }
        let timing = choice(&format!("{key}.at"), f.at.clone(), ForceTiming::Last)?;
        out.push(PointForce { vertex, value: f.value, timing });
    }
    Ok(out)
}

/// `[solver]`.
fn solver(s: Option<SolverToml>) -> Result<SolverOptions, Invalid> {
    let mut solver = SolverOptions::default();
    let Some(s) = s else { return Ok(solver) };
    solver.backend = choice("[solver].backend", s.backend, solver.backend)?;
    if let Err(e) = solver.backend.solver() {
        return Err(invalid("[solver].backend", SceneProblem::Backend(e)));
    }
    solver.mode = choice("[solver].mode", s.mode, solver.mode)?;
    solver.stepping = choice("[solver].stepping", s.stepping, solver.stepping)?;
    solver.precision = choice("[solver].precision", s.precision, solver.precision)?;
    solver.constraints = choice("[solver].constraints", s.constraints, solver.constraints)?;
    solver.method = choice("[solver].method", s.method, solver.method)?;
    if solver.method.is_chainmail() {
        return Err(range(
            "[solver].method",
            "ffm or fem (ChainMail is interactive only: probe, compare, view)",
            solver.method,
        ));
    }
    solver.penalty = s.penalty.unwrap_or(DEFAULT_PENALTY);
    if !(solver.penalty.is_finite() && solver.penalty > 0.0) {
        return Err(range("[solver].penalty", "positive", solver.penalty));
    }
    Ok(solver)
}

/// `[[plate]]` tables, checked against the rest shape (`timed`: the scene has `[time]`,
/// which a plate driven by a force needs).
fn plates(specs: &[PlateToml], vertices: &VertexMap<'_>, timed: bool) -> Result<Vec<Plate>, Invalid> {
    let mut plates = Vec::with_capacity(specs.len());
    for (k, p) in specs.iter().enumerate() {
        let key = format!("[[plate]] #{}", k + 1);
        if p.point.iter().any(|c| !c.is_finite()) {
            return Err(range(format!("{key}.point"), "finite", format!("{:?}", p.point)));
        }
        if !p.travel.is_finite() {
            return Err(range(format!("{key}.travel"), "finite", p.travel));
        }
        let m = vertices.metres;
        let normal_invalid =
            || range(format!("{key}.normal"), "finite and non-zero", format!("{:?}", p.normal));
        let plate = match p.force {
            None => Plate::new(p.point.map(|c| c * m), p.normal, p.travel * m).ok_or_else(normal_invalid)?,
            Some(_) if p.travel != 0.0 => {
                let problem = "a plate is driven by its travel or by a force, not both: remove one";
                return Err(invalid(format!("{key}.force"), SceneProblem::Conflict(problem)));
            }
            Some(f) if !(f.is_finite() && f >= 0.0) => {
                return Err(range(
                    format!("{key}.force"),
                    "finite and at least 0 (N, pressing on the body)",
                    f,
                ));
            }
            Some(_) if !timed => {
                let problem = "a plate driven by a force needs a [time] table (a run without one drives plates by their travel)";
                return Err(invalid(format!("{key}.force"), SceneProblem::Conflict(problem)));
            }
            Some(f) => Plate::driven_by(p.point.map(|c| c * m), p.normal, f).ok_or_else(normal_invalid)?,
        };
        plates.push(plate);
    }
    let (lo, hi) = fibfluid_geometry::bounding_box(&vertices.positions);
    let diagonal = fibfluid_geometry::vec3::norm(fibfluid_geometry::vec3::sub(hi, lo));
    if let Err((k, problem)) = check_plates(&plates, &vertices.positions, PLATE_REST_TOLERANCE * diagonal) {
        let problem = match problem {
            PlateProblem::FacesAway => SceneProblem::PlateFacesAway,
            PlateProblem::CutsBody { vertex, depth } => {
                SceneProblem::PlateCutsBody { vertex: vertices.file_index(vertex), depth }
            }
        };
        return Err(invalid(format!("[[plate]] #{}", k + 1), problem));
    }
    Ok(plates)
}

/// `[[grasp]]` tables: each patch is the vertices within `radius` of `vertex` (lengths in
/// the mesh's unit), refused when it holds a vertex a `[[fix]]` fixes.
fn grasps(
    specs: &[GraspToml],
    vertices: &VertexMap<'_>,
    constraints: &Constraints,
) -> Result<Vec<fibfluid_fem::hyper::Grasp>, Invalid> {
    let mut out = Vec::with_capacity(specs.len());
    for (k, g) in specs.iter().enumerate() {
        let key = format!("[[grasp]] #{}", k + 1);
        let centre = vertices.mesh_index(g.vertex, &format!("{key}.vertex"))?;
        if !(g.radius.is_finite() && g.radius > 0.0) {
            return Err(range(format!("{key}.radius"), "positive (in the mesh's unit)", g.radius));
        }
        if let Some(c) = g.translation.iter().find(|c| !c.is_finite()) {
            return Err(range(format!("{key}.translation"), "finite", c));
        }
        let rotation = g.rotation.unwrap_or([0.0; 3]);
        if let Some(c) = rotation.iter().find(|c| !c.is_finite()) {
            return Err(range(format!("{key}.rotation"), "finite (radians)", c));
        }
        let m = vertices.metres;
        let patch = fibfluid_fem::hyper::Grasp::patch(&vertices.positions, centre, g.radius * m);
        if patch.iter().any(|&v| (0..3).any(|a| constraints.get(v, a).is_some())) {
            return Err(invalid(
                format!("{key}.radius"),
                SceneProblem::Conflict(
                    "the patch holds a vertex that a [[fix]] fixes (a vertex cannot be both clamped and grasped): lower the radius or move the grasp",
                ),
            ));
        }
        out.push(fibfluid_fem::hyper::Grasp {
            vertices: patch,
            translation: g.translation.map(|c| c * m),
            rotation,
        });
    }
    Ok(out)
}
