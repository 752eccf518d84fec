//! `fibfluid view`: a live viewer of a scene's interactive body (a local web page and a
//! WebSocket protocol, `docs/viewer.md`).

use std::path::PathBuf;
use std::sync::Arc;

use fibfluid::interact::{Interactive, Method, MethodBody, ProbeError, build_body};
use fibfluid::{Choice, Scene, Shape};
use fibfluid_viewer::{BodyFactory, Server, ServerOptions, ViewMesh, ViewerError};

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
    /// Method of the body (ffm, fem, tsve-chainmail, generalized-chainmail); default: the
    /// scene's `[solver] method`. The page can switch between the available ones.
    #[arg(long)]
    method: Option<Method>,
    #[command(flatten)]
    response: crate::response_flags::ResponseFlags,
    /// Most clients at once (each has its own body; the factorization or the full
    /// precompute is shared).
    #[arg(long, default_value_t = 8)]
    max_clients: usize,
}

/// Runs `fibfluid view` until the process is stopped (Ctrl-C).
pub fn run(args: &ViewArgs) -> Result<(), crate::CliError> {
    if args.max_clients == 0 {
        return Err(crate::CliError::Flag {
            flag: "max-clients",
            value: "0".into(),
            problem: "must be at least 1",
        });
    }
    let scene = Scene::load(&args.scene)?;
    let method = args.method.unwrap_or(scene.model.solver.method);
    for w in fibfluid::ineffective_interactive(&scene) {
        tell!("warning: {w}");
    }
    let opts = args.response.options(fibfluid::interact::RefreshMode::Background, &scene, &[method])?;
    let Shape::Surface(file) = &scene.shape else {
        return Err(ProbeError::NotASurface { scene: scene.display_name() }.into());
    };
    let server_opts = ServerOptions {
        host: args.host.clone(),
        port: args.port,
        max_clients: args.max_clients,
        // FFM is served only when its precompute is built (started with `--method ffm`); the
        // FEM when the scene gives [tissue].
        methods: std::iter::once(method)
            .chain(Method::ALL.iter().copied().filter(|m| *m != method && *m != Method::Ffm))
            .filter(|m| *m != Method::Fem || scene.tissue.is_some())
            .collect(),
        ..ServerOptions::default()
    };
    // Bind first: a port in use is reported before the (possibly long) precompute.
    let server = Server::bind(server_opts)?;
    for warning in server.warnings() {
        tell!("{warning}");
    }
    // The FFM body is built once and shared by every client (each gets a clone: its own
    // holds and frame); ChainMail bodies are cheap and built per client. With the lazy
    // response (the default) the first frame follows the base solve: a vertex's columns are
    // computed with the kept factorization when a client first touches it.
    let ffm = if method == Method::Ffm {
        tell!(
            "building the ffm body of {} ({} vertices, {} response)...",
            scene.name,
            scene.n_vertices(),
            opts.precompute
        );
        let pb = build_body(&scene, &opts)?;
        tell!(
            "  base solve {:.2} s, precompute {:.2} s, {:.1} MiB",
            pb.base_seconds,
            pb.precompute_seconds,
            pb.body.memory_bytes() as f64 / 1048576.0
        );
        Some(pb.body)
    } else {
        None
    };
    // ChainMail and FEM bodies are built per client (a voxelization, or a sparse factor),
    // through the same factory as `probe` and `compare`, with the flags' options.
    let chainmail =
        move |scene: &Scene, method: Method| -> Result<Box<dyn Interactive + Send>, ViewerError> {
            MethodBody::build(scene, &scene.chainmail, method, &opts)
                .map(MethodBody::into_interactive)
                .map_err(|e| ViewerError::Build { method, source: Box::new(e) })
        };
    let mesh = match &ffm {
        Some(body) => ViewMesh::new(file, body)?,
        None => ViewMesh::new(file, chainmail(&scene, method)?.as_ref())?,
    };
    let scene_for_clients = scene.clone();
    let factory: BodyFactory = Arc::new(move |method: Method| match (method, &ffm) {
        (Method::Ffm, Some(body)) => Ok(Box::new(body.clone()) as Box<dyn Interactive + Send>),
        (Method::Ffm, None) => {
            Err(ViewerError::UnsupportedMethod { method: method.to_string(), available: available(false) })
        }
        (other, _) => chainmail(&scene_for_clients, other),
    });
    say!("fibfluid view: {} ({}, {}; Ctrl-C stops)", server.url(), scene.name, method);
    server.run(mesh, factory)?;
    Ok(())
}

/// The methods a viewer serves: ChainMail always; FFM when its precompute was built (the
/// viewer was started with FFM: `--method ffm` or a scene whose `[solver] method` is ffm); the FEM with `[tissue]`.
fn available(ffm: bool) -> String {
    Method::ALL.iter().filter(|m| ffm || **m != Method::Ffm).map(|m| m.name()).collect::<Vec<_>>().join(", ")
}
