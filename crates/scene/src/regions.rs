//! `[[region]]`: regions of other tissue inside the body (for the finite-element method).
//!
//! ```toml
//! [[region]]
//! name = "lesion"                 # optional; reports say "region k" otherwise
//! mesh = "lesion.obj"             # a closed surface, in the [mesh]'s unit (and `scale`)
//! # or: box = { min = [x, y, z], max = [x, y, z] }, in the [mesh]'s unit
//! # or, with [mesh].image: label = 2    (the surface of that label, full resolution)
//! [region.tissue]
//! young = 24000.0                 # Pa
//! poisson = 0.45
//! density = 1000.0                # kg/m^3
//! ```
//!
//! A region's tissue takes the body's `[tissue] model`; giving `model` in a region is
//! refused (one law per body).

use std::path::{Path, PathBuf};

use fibfluid_fem::{Region, RegionShape};
use fibfluid_geometry::{LabelImage, ReadOptions, load_mesh_with};
use fibfluid_sim::{LengthUnit, NamedRegion};

use crate::error::SceneProblem;
use crate::invalid::{Invalid, invalid, range};
use crate::spec::TissueRegionToml;

/// The scene's regions, in metres, with the `[mesh]`'s unit and scale and its label image
/// (for `label` regions: its path, and the image when the body was already read from it;
/// otherwise it is read at the first `label` region); `body_tissue` must be given when any
/// region is.
pub(crate) fn regions(
    specs: Vec<TissueRegionToml>,
    dir: &Path,
    (unit, mesh_scale): (LengthUnit, f64),
    image: Option<(PathBuf, Option<LabelImage>)>,
    body_tissue: Option<&fibfluid_fem::Tissue>,
) -> Result<Vec<NamedRegion>, Invalid> {
    let (image_path, mut image) = match image {
        Some((path, read)) => (Some(path), read),
        None => (None, None),
    };
    let mut out = Vec::with_capacity(specs.len());
    for (k, spec) in specs.into_iter().enumerate() {
        let key = format!("[[region]] #{}", k + 1);
        let Some(body) = body_tissue else {
            return Err(invalid(key, SceneProblem::Conflict("a region needs the body's [tissue] table")));
        };
        if spec.tissue.model.is_some() {
            return Err(invalid(
                format!("{key} tissue.model"),
                SceneProblem::Conflict("a region takes the body's [tissue] model; remove `model` here"),
            ));
        }
        let (tissue, _) = crate::tissue_table::tissue(spec.tissue)
            .map_err(|e| Invalid { key: Some(format!("{key} tissue")), ..e })?;
        let tissue = tissue.with_model(body.model());
        let metres = unit.metres();
        let origin = match (&spec.mesh, &spec.r#box, &spec.label) {
            (Some(path), _, _) => format!("mesh {path}"),
            (None, None, Some(label)) => format!("label {label}"),
            _ => "box".to_string(),
        };
        let shape = match (spec.mesh, spec.r#box, spec.label) {
            (None, None, Some(label)) => label_shape(&key, image_path.as_deref(), &mut image, label)?,
            (Some(path), None, None) => {
                let file = dir.join(&path);
                if !file.exists() {
                    return Err(invalid(
                        format!("{key} mesh"),
                        SceneProblem::MeshNotFound { given: path, resolved: file },
                    ));
                }
                let scale = Some(mesh_scale * metres).filter(|s| *s != 1.0);
                let mesh = load_mesh_with(&file, &ReadOptions { scale, ..Default::default() })
                    .map_err(|e| invalid(format!("{key} mesh"), SceneProblem::Mesh(e)))?;
                RegionShape::Surface {
                    positions: mesh.mesh.positions().to_vec(),
                    triangles: mesh.mesh.triangles().to_vec(),
                }
            }
            (None, Some(b), None) => {
                if !(0..3).all(|a| b.min[a].is_finite() && b.max[a].is_finite() && b.min[a] < b.max[a]) {
                    return Err(range(
                        format!("{key} box"),
                        "finite, with min < max on every axis",
                        format!("{:?} .. {:?}", b.min, b.max),
                    ));
                }
                RegionShape::Box { min: b.min.map(|c| c * metres), max: b.max.map(|c| c * metres) }
            }
            _ => {
                return Err(invalid(
                    key,
                    SceneProblem::Conflict("give a region one of `mesh`, `box` or `label`"),
                ));
            }
        };
        let name = spec.name.unwrap_or_else(|| format!("region {}", k + 1));
        out.push(NamedRegion { name, origin, region: Region { shape, tissue } });
    }
    Ok(out)
}

/// The region of `label` in the scene's label image (at `path`; read into `image` unless it
/// already holds it): the label's surface at the image's full resolution, cavities filled
/// (a label around another gives its outer surface).
fn label_shape(
    key: &str,
    path: Option<&Path>,
    image: &mut Option<LabelImage>,
    label: i64,
) -> Result<RegionShape, Invalid> {
    use fibfluid_geometry::{LabelSelection, SurfaceOptions, extract_surface, read_nifti};
    let Some(path) = path else {
        return Err(invalid(
            format!("{key} label"),
            SceneProblem::Conflict("a region's `label` needs the body's [mesh].image"),
        ));
    };
    let Some(label) = u32::try_from(label).ok().filter(|&l| l > 0) else {
        return Err(range(format!("{key} label"), "a label between 1 and 4294967295", label));
    };
    if image.is_none() {
        *image = Some(read_nifti(path).map_err(|e| invalid(format!("{key} label"), SceneProblem::Image(e)))?);
    }
    let Some(image) = image.as_ref() else { unreachable!("read just above") };
    let opts =
        SurfaceOptions { selection: LabelSelection::Label(label), fill_cavities: true, ..Default::default() };
    let surface = extract_surface(image, &opts).map_err(|source| {
        invalid(format!("{key} label"), SceneProblem::Surface { path: path.to_path_buf(), source })
    })?;
    Ok(RegionShape::Surface {
        positions: surface.mesh.positions().to_vec(),
        triangles: surface.mesh.triangles().to_vec(),
    })
}
