//! A scene's body as a ChainMail lattice a tool can grab: TSVE-ChainMail or Generalized
//! ChainMail behind the method-neutral [`Interactive`] trait, so that `fibfluid probe` and
//! `fibfluid compare` replay the same path on it as on the fiber–fluid method.
//!
//! The scene's closed surface is voxelized into a lattice and each vertex is embedded with
//! trilinear weights in its grid cell ([`fibfluid_chainmail::Embedding`]); the surface
//! follows the elements. ChainMail is displacement-driven: a grab moves the elements that
//! carry the grabbed vertex (the free corners of its grid cell, the element nearest the
//! vertex among them) to their rest positions plus the grab's displacement, so the vertex
//! itself lands where the tool puts it, and the move propagates through the lattice; with
//! TSVE the lattice then relaxes (volume and strain energy) with the grabbed elements held.
//! (Moving only the nearest element leaves the vertex short of the tool: its other seven
//! corners lag by up to the CBR slack; on the sphere poke path the grabbed vertex reached
//! 64 % of the prescribed displacement.) All sponsors of one grab share one displacement,
//! which is the case where the paper's time-saving scheme is exact. A frame with
//! nothing held relaxes with nothing held (TSVE: back toward rest; Generalized: nothing
//! moves, it has no restoring mechanism). The scene's loads (gravity, point forces) are not
//! applied: ChainMail has no forces. Fixed vertices fix the elements that carry them.

use std::collections::BTreeMap;
use std::time::Instant;

use fibfluid_chainmail::{
    Embedding, GeneralizedMaterial, Lattice, Material, PropagationOptions, PropagationReport, RelaxOptions,
    RelaxReport, Scheme, TsveMaterial,
};
use fibfluid_geometry::Vec3;
use fibfluid_geometry::vec3::{add, sub};
use fibfluid_sim::{Method, Model, Shape};

use crate::chainmail_settings::{ChainmailSettings, Variant};
use crate::{Hold, Holds, InteractError, Interactive, PushRule, Surface};

/// The material of a ChainMail body.
#[derive(Clone, Debug)]
enum BodyMaterial {
    Tsve(TsveMaterial),
    Generalized(GeneralizedMaterial),
}

impl BodyMaterial {
    fn get(&self) -> &dyn Material {
        match self {
            BodyMaterial::Tsve(m) => m,
            BodyMaterial::Generalized(m) => m,
        }
    }
}

/// The exhaustive propagation of one frame stops after this many processings per element
/// (a push that the fixed elements make impossible would otherwise run to the crate's
/// default of 64 per element every frame).
pub const MAX_PROCESSED_PER_ELEMENT: usize = 8;

/// Scale of each strain-energy correction (Eq. 17) in the relaxation. At full strength the
/// energy constraint pulls the tetrahedra toward their rest shape and partly undoes the
/// volume correction (crates/chainmail README: 4.99 % volume lost on its 12^3 push against
/// 1.49 % at 0.1, with the same return to rest).
pub const ENERGY_STIFFNESS: f64 = 0.1;

/// What the last frame of a [`ChainmailBody`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FrameWork {
    /// The propagation (none in a frame with nothing held).
    pub propagation: Option<PropagationReport>,
    /// The relaxation (TSVE only).
    pub relaxation: Option<RelaxReport>,
}

/// A scene's body as a ChainMail lattice (see the module documentation).
#[derive(Debug)]
pub struct ChainmailBody {
    variant: Variant,
    lattice: Lattice,
    embedding: Embedding,
    material: BodyMaterial,
    propagation: PropagationOptions,
    relax: RelaxOptions,
    /// Rest shape and current frame.
    surface: Surface,
    holds: Holds,
    work: FrameWork,
    setup_seconds: f64,
}

/// Why a ChainMail body cannot be built.
#[derive(Debug, thiserror::Error)]
pub enum ChainmailBodyError {
    /// The scene is a 2D polygon.
    #[error("ChainMail needs a surface mesh; this scene is a 2D polygon")]
    NotASurface,
    /// The body has cavities (not built for ChainMail).
    #[error("ChainMail does not run a body with cavities (the finite-element method does)")]
    Cavities,
    /// The lattice would not fit in the memory budget (refused before allocating).
    #[error(
        "the ChainMail lattice at spacing {spacing} needs up to {bytes} bytes ({:.2} GiB), but only {available} bytes ({:.2} GiB) may be used; use a larger [chainmail] spacing",
        *bytes as f64 / 1073741824.0,
        *available as f64 / 1073741824.0
    )]
    OutOfMemory {
        /// The spacing.
        spacing: f64,
        /// Bytes needed (upper bound).
        bytes: u128,
        /// Bytes that may be used.
        available: u64,
    },
    /// Voxelization or material failed.
    #[error("ChainMail: {0}")]
    Chainmail(#[from] fibfluid_chainmail::ChainmailError),
    /// Every element carrying a vertex is fixed, so no element can be grabbed there.
    #[error("every fixed vertex's cell covers the body: no element is free to move")]
    AllFixed,
}

fn chainmail_err(e: fibfluid_chainmail::ChainmailError) -> InteractError {
    InteractError::Invalid(format!("ChainMail: {e}"))
}

impl ChainmailBody {
    /// Builds the body of a scene with the given variant (the scene's `[chainmail]` section
    /// gives the rest), refusing a lattice over `budget` bytes before allocating it.
    pub fn from_model(
        scene: &Model,
        settings: &ChainmailSettings,
        variant: Variant,
        budget: u64,
    ) -> Result<Self, ChainmailBodyError> {
        let Shape::Surface(file) = &scene.shape else { return Err(ChainmailBodyError::NotASurface) };
        if !file.validation.cavities.is_empty() {
            return Err(ChainmailBodyError::Cavities);
        }
        let rest = file.mesh.positions().to_vec();
        let fixed_axis = (0..rest.len())
            .map(|v| {
                (0..3).find(|&c| scene.constraints.get(v, c).is_some()).map(|c| fibfluid_geometry::AXES[c])
            })
            .collect();
        Self::new(rest, file.mesh.triangles(), fixed_axis, settings, variant, budget)
    }

    /// Builds a body from a surface (`rest`, `triangles`), the first fixed axis of each
    /// vertex (`None`: free), the settings and the variant.
    pub fn new(
        rest: Vec<Vec3>,
        triangles: &[[u32; 3]],
        fixed_axis: Vec<Option<char>>,
        settings: &ChainmailSettings,
        variant: Variant,
        budget: u64,
    ) -> Result<Self, ChainmailBodyError> {
        let start = Instant::now();
        let spacing = settings.spacing_for(&rest);
        let bytes = settings.lattice_bytes(&rest);
        if bytes > budget as u128 {
            return Err(ChainmailBodyError::OutOfMemory { spacing, bytes, available: budget });
        }
        let (mut lattice, embedding) = Lattice::embed_surface(&rest, triangles, spacing)?;
        for (v, f) in fixed_axis.iter().enumerate() {
            if f.is_some()
                && let Some(elements) = embedding.elements(v)
            {
                for e in elements {
                    lattice.set_inverse_mass(e, 0.0)?;
                }
            }
        }
        if (0..lattice.len()).all(|e| lattice.inverse_mass(e).is_ok_and(|w| w == 0.0)) {
            return Err(ChainmailBodyError::AllFixed);
        }
        let material = match variant {
            Variant::Tsve => BodyMaterial::Tsve(settings.tsve_material(lattice.rest_positions())),
            Variant::Generalized => BodyMaterial::Generalized(settings.generalized_material()),
        };
        material.get().validate(lattice.len())?;
        let scheme = if settings.tss { Scheme::Auto } else { Scheme::Exhaustive };
        let relax = RelaxOptions {
            max_iterations: settings.relaxation,
            energy_stiffness: ENERGY_STIFFNESS,
            ..RelaxOptions::default()
        };
        let n_elements = lattice.len();
        Ok(Self {
            variant,
            lattice,
            embedding,
            material,
            propagation: PropagationOptions {
                scheme,
                max_processed: MAX_PROCESSED_PER_ELEMENT * n_elements,
                ..PropagationOptions::default()
            },
            relax,
            surface: Surface::at_rest(rest),
            holds: Holds::with_first_axes(&fixed_axis, PushRule::Refused),
            work: FrameWork::default(),
            setup_seconds: start.elapsed().as_secs_f64(),
        })
    }

    /// The variant.
    pub fn variant(&self) -> Variant {
        self.variant
    }

    /// The lattice (current element positions, rest, tetrahedra).
    pub fn lattice(&self) -> &Lattice {
        &self.lattice
    }

    /// The surface's embedding in the lattice.
    pub fn embedding(&self) -> &Embedding {
        &self.embedding
    }

    /// Seconds of the voxelization and embedding.
    pub fn setup_seconds(&self) -> f64 {
        self.setup_seconds
    }

    /// What the last update did (elements moved, processings, CBR checks, sweeps).
    pub fn last_work(&self) -> FrameWork {
        self.work
    }

    /// The elements a grab of `vertex` moves: the free (not fixed) elements among the eight
    /// carrying the vertex, nearest first; empty when all are fixed or the vertex is unknown.
    pub fn grabbed_elements(&self, vertex: usize) -> Vec<usize> {
        let (Some(elements), Some(&p)) = (self.embedding.elements(vertex), self.surface.rest.get(vertex))
        else {
            return Vec::new();
        };
        let rest = self.lattice.rest_positions();
        let mut free: Vec<usize> =
            elements.into_iter().filter(|&e| self.lattice.inverse_mass(e).is_ok_and(|w| w > 0.0)).collect();
        free.sort_by(|&a, &b| {
            fibfluid_geometry::vec3::dist(rest[a], p).total_cmp(&fibfluid_geometry::vec3::dist(rest[b], p))
        });
        free.dedup();
        free
    }
}

impl Interactive for ChainmailBody {
    fn method(&self) -> Method {
        match self.variant {
            Variant::Tsve => Method::TsveChainmail,
            Variant::Generalized => Method::GeneralizedChainmail,
        }
    }

    fn surface(&self) -> &Surface {
        &self.surface
    }

    fn holds(&self) -> &Holds {
        &self.holds
    }

    fn holds_mut(&mut self) -> &mut Holds {
        &mut self.holds
    }

    /// As the trait's, and refused when every lattice element carrying the vertex is fixed.
    fn grab(&mut self, vertex: usize, displacement: Vec3) -> crate::Result<()> {
        self.holds.check_grab(vertex, displacement)?;
        if self.grabbed_elements(vertex).is_empty() {
            return Err(InteractError::Invalid(format!(
                "vertex {vertex}: every lattice element carrying it is fixed; it cannot be grabbed"
            )));
        }
        self.holds.grab(vertex, displacement)
    }

    fn update(&mut self) -> crate::Result<&[(usize, Vec3)]> {
        // Grabs of vertices sharing an element move it by their mean displacement.
        let mut sponsors: BTreeMap<usize, (Vec3, f64)> = BTreeMap::new();
        for (v, hold) in self.holds.iter() {
            let Hold::Grab { displacement: d } = hold else { continue };
            for e in self.grabbed_elements(v) {
                let s = sponsors.entry(e).or_insert(([0.0; 3], 0.0));
                s.0 = add(s.0, d);
                s.1 += 1.0;
            }
        }
        let rest = self.lattice.rest_positions();
        let moves: Vec<(usize, Vec3)> =
            sponsors.iter().map(|(&e, &(d, k))| (e, add(rest[e], [d[0] / k, d[1] / k, d[2] / k]))).collect();
        let held: Vec<usize> = moves.iter().map(|m| m.0).collect();
        let material = self.material.get();
        let mut work = FrameWork::default();
        let saved = self.lattice.positions().to_vec();
        let result = (|| {
            if !moves.is_empty() {
                work.propagation = Some(self.lattice.propagate(material, &moves, &self.propagation)?);
            }
            if self.variant == Variant::Tsve && self.relax.max_iterations > 0 {
                work.relaxation = Some(self.lattice.relax(material, &held, &self.relax)?);
            }
            Ok(())
        })();
        if let Err(e) = result {
            // Keep the previous frame current (same length: cannot fail).
            let _ = self.lattice.set_positions(&saved);
            return Err(chainmail_err(e));
        }
        self.work = work;
        let s = &mut self.surface;
        self.embedding.positions_into(&self.lattice, &mut s.positions);
        for ((f, p), r) in s.field.iter_mut().zip(&s.positions).zip(&s.rest) {
            *f = sub(*p, *r);
        }
        s.frame += 1;
        Ok(&[])
    }

    fn memory_bytes(&self) -> usize {
        let material = match &self.material {
            BodyMaterial::Tsve(m) => m.alpha.len() * 24,
            BodyMaterial::Generalized(_) => 72,
        };
        self.lattice.memory_bytes()
            + self.embedding.memory_bytes()
            + material
            + self.surface.rest.len() * 3 * 24
    }
}
