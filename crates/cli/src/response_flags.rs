//! The flags of an interactive body shared by `probe`, `compare` and `view`: the FFM
//! response's storage and precompute, the memory budget and the two-rate body's refreshes.

use fibfluid::Scene;
use fibfluid::interact::{Method, Precompute, ProbeOptions, RefreshMode, Storage};

/// The flags of the precomputed response, shared by `probe`, `compare` and `view`.
#[derive(clap::Args)]
pub struct ResponseFlags {
    /// Storage of FFM's full precomputed response (f64, f32; the lazy response is f64).
    #[arg(long, default_value = "f64")]
    pub precision: Storage,
    /// FFM's response: `lazy` computes a vertex's compliance columns when it is first
    /// touched, with the base solve's factorization (the first frame comes right after the
    /// base solve); `full` inverts the stiffness first (N^3 flops, N^2 words: every vertex
    /// ready at once, for haptic devices).
    #[arg(long, default_value = "lazy")]
    pub precompute: Precompute,
    /// Memory budget in bytes (default: half the available memory).
    #[arg(long, value_name = "BYTES")]
    pub max_memory: Option<u64>,
    /// The neo-Hookean FEM body's linearization is refreshed (one iteration: Newton's, or
    /// a chord step on the kept factor, `--chord-refreshes`) before every K-th frame, in
    /// the frame loop. Default: `probe` and `compare` pick K from the
    /// body's counts (reproducible); `view` refreshes on a second thread.
    #[arg(long, value_name = "K")]
    pub refresh_every: Option<u64>,
    /// Neo-Hookean FEM body: refreshes that keep the tangent's factor and move only the
    /// state (chord iterations) between two that factor it; 0: every refresh is a Newton
    /// iteration. Default: 4.
    #[arg(long, value_name = "N")]
    pub chord_refreshes: Option<usize>,
}

impl ResponseFlags {
    /// The probe options these flags set; `refresh` unless `--refresh-every` is given.
    ///
    /// Errors: `--refresh-every 0`, and `--refresh-every` or `--chord-refreshes` when none
    /// of `methods` builds a neo-Hookean FEM body of `scene` (the only body they act on).
    pub fn options(
        &self,
        refresh: RefreshMode,
        scene: &Scene,
        methods: &[Method],
    ) -> Result<ProbeOptions, crate::CliError> {
        if self.refresh_every == Some(0) {
            return Err(crate::CliError::Flag {
                flag: "refresh-every",
                value: "0".into(),
                problem: "must be at least 1",
            });
        }
        let neo_hookean = scene.tissue.is_some_and(|t| !t.is_linear());
        let two_rate = neo_hookean && methods.contains(&Method::Fem);
        let given = [
            ("refresh-every", self.refresh_every.map(|k| k.to_string())),
            ("chord-refreshes", self.chord_refreshes.map(|n| n.to_string())),
        ];
        if let Some((flag, Some(value))) = given.into_iter().find(|(_, v)| v.is_some())
            && !two_rate
        {
            return Err(crate::CliError::Flag {
                flag,
                value,
                problem: "acts only on a neo-Hookean FEM body (--method fem on a scene whose [tissue] model is \"neo-hookean\")",
            });
        }
        Ok(ProbeOptions {
            storage: self.precision,
            precompute: self.precompute,
            max_memory_bytes: self.max_memory,
            refresh: self.refresh_every.map_or(refresh, RefreshMode::EveryFrames),
            chord_refreshes: self.chord_refreshes,
        })
    }
}
