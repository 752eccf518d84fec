//! `fibfluid view`: a live viewer of a scene's interactive body (a local web page and a
//! WebSocket protocol, `docs/viewer.md`).

use std::path::PathBuf;
use std::sync::Arc;

use fibfluid::linalg::{Choice, impl_choice};
use fibfluid::probe::interact::{Interactive, Storage};
use fibfluid::probe::{ProbeOptions, build_body};
use fibfluid::{Scene, Shape};
use fibfluid_viewer::{BodyFactory, Server, ServerOptions, ViewMesh, ViewerError};

/// The method a viewer's body uses.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum ViewMethod {
    /// The fiber–fluid method's precomputed response (`fibfluid::probe`).
    #[default]
    Ffm,
    /// TSVE ChainMail (not yet available in the viewer).
    TsveChainmail,
    /// Generalized ChainMail (not yet available in the viewer).
    GeneralizedChainmail,
}

impl Choice for ViewMethod {
    const WHAT: &'static str = "method";
    const ALL: &'static [Self] =
        &[ViewMethod::Ffm, ViewMethod::TsveChainmail, ViewMethod::GeneralizedChainmail];
    fn name(self) -> &'static str {
        match self {
            ViewMethod::Ffm => "ffm",
            ViewMethod::TsveChainmail => "tsve-chainmail",
            ViewMethod::GeneralizedChainmail => "generalized-chainmail",
        }
    }
}
impl_choice!(ViewMethod);

/// The methods this build's viewer can build a body for.
const AVAILABLE: &[ViewMethod] = &[ViewMethod::Ffm];

/// Arguments of `fibfluid view`.
#[derive(clap::Args)]
pub struct ViewArgs {
    /// Scene TOML file (its body: paper mode about the rest shape, the scene's loads as the
    /// base state, as `fibfluid probe`).
    scene: PathBuf,
    /// Port (0: pick a free one).
    #[arg(long, default_value_t = 8765)]
    port: u16,
    /// Address to listen on; the default lets only this machine connect.
    #[arg(long, default_value = "127.0.0.1")]
    host: String,
    /// Method of the body (ffm, tsve-chainmail, generalized-chainmail); the page can switch
    /// between the available ones.
    #[arg(long, default_value = "ffm")]
    method: ViewMethod,
    /// Storage of the FFM precomputed response (f64, f32); shared by every client.
    #[arg(long, default_value = "f64")]
    precision: Storage,
    /// Memory budget in bytes (default: half the available memory).
    #[arg(long, value_name = "BYTES")]
    max_memory: Option<u64>,
    /// Most clients at once (each has its own body; the precompute is shared).
    #[arg(long, default_value_t = 8)]
    max_clients: usize,
}

/// Runs `fibfluid view` until the process is stopped (Ctrl-C).
pub fn run(args: &ViewArgs) -> Result<(), crate::CliError> {
    if !AVAILABLE.contains(&args.method) {
        return Err(crate::CliError::Flag {
            flag: "method",
            value: args.method.to_string(),
            problem: "not available in the viewer yet (available: ffm)",
        });
    }
    if args.max_clients == 0 {
        return Err(crate::CliError::Flag {
            flag: "max-clients",
            value: "0".into(),
            problem: "must be at least 1",
        });
    }
    let scene = Scene::load(&args.scene)?;
    let Shape::Surface(file) = &scene.shape else {
        return Err(fibfluid::Error::from(fibfluid::probe::ProbeError::NotASurface).into());
    };
    let server_opts = ServerOptions {
        host: args.host.clone(),
        port: args.port,
        max_clients: args.max_clients,
        methods: std::iter::once(args.method)
            .chain(ViewMethod::ALL.iter().copied().filter(|m| *m != args.method))
            .map(|m| m.name().to_string())
            .collect(),
    };
    // Bind first: a port in use is reported before the (possibly long) precompute.
    let server = Server::bind(server_opts)?;
    let opts = ProbeOptions { storage: args.precision, max_memory_bytes: args.max_memory };
    eprintln!("building the {} body of {} ({} vertices)...", args.method, scene.name, scene.n_vertices());
    let pb = build_body(&scene, &opts)?;
    eprintln!(
        "  base solve {:.2} s, precompute {:.2} s, {:.1} MiB",
        pb.base_seconds,
        pb.precompute_seconds,
        pb.body.memory_bytes() as f64 / 1048576.0
    );
    let mesh = ViewMesh::new(file, &pb.body)?;
    let proto = pb.body;
    // Each client gets a clone of the built body: the precomputed response is shared, the
    // holds and the frame are the client's own.
    let factory: BodyFactory = Arc::new(move |name: &str| match name.parse::<ViewMethod>() {
        Ok(ViewMethod::Ffm) => Ok(Box::new(proto.clone()) as Box<dyn Interactive + Send>),
        _ => Err(ViewerError::UnsupportedMethod {
            method: name.to_string(),
            available: AVAILABLE.iter().map(|m| m.name()).collect::<Vec<_>>().join(", "),
        }),
    });
    println!("fibfluid view: {} ({}, {}; Ctrl-C stops)", server.url(), scene.name, args.method);
    server.run(mesh, factory)?;
    Ok(())
}
