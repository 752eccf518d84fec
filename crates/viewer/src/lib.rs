//! A live viewer: drag an interactive body in a browser, or drive it from any program
//! through a small documented protocol (`docs/viewer.md`).
//!
//! The server knows only [`Interactive`](fibfluid_interact::Interactive) bodies and
//! meshes. It listens on one [`std::net::TcpListener`] and routes each connection by its
//! request head:
//!
//! - `GET /`: the page (HTML, JavaScript and CSS compiled into the binary: works offline);
//! - `GET /mesh`: the rest shape, `{"positions": [...], "triangles": [...], "fixed": [...]}`
//!   in the input file's vertex order;
//! - `GET /info`: the methods this server can build and its client limit;
//! - WebSocket `/ws?method=NAME`: one body per client, built by a factory closure
//!   ([`BodyFactory`]). Client messages `{"grab": V, "to": [x, y, z]}`, `{"release": V}`,
//!   `{"reset": true}`; each batch of messages read together is answered by one text
//!   message `{"frame": k, "reactions": [[V, fx, fy, fz], ...], "latency_us": t,
//!   "warnings": [...]}` and one binary message of `3 N` little-endian `f32` positions
//!   (messages that arrive faster than frames are coalesced: the last state wins). Every
//!   frame is checked by the result guards
//!   ([`FrameGuards`](fibfluid_interact::FrameGuards): volume, displacement,
//!   inverted faces, and the small-strain validity of a finite-element body); `warnings`
//!   lists those that fired, and a non-finite answer is an error instead of a frame. A bad
//!   message is answered by `{"error": "..."}` and the connection stays open.
//!
//! One thread per connection; plain blocking I/O (tungstenite, no async runtime). The
//! server is meant to survive hostile clients: open connections are capped (extra ones
//! are answered 503), request heads must arrive whole within a timeout and a size limit,
//! malformed requests and handshakes are answered 400 (426 for a WebSocket version other
//! than 13), a message too big or a protocol violation is answered by a close frame (1009,
//! 1002, 1007), a client that does not read is dropped after a write timeout, and a
//! failing `accept` (out of descriptors) pauses instead of spinning. Binding an address
//! other than loopback yields a warning ([`binding_warning`], [`Server::warnings`]).

mod error;
mod http;
mod mesh;
mod protocol;
mod server;

pub use error::{Result, ViewerError};
pub use fibfluid_interact::ToolLoad;
pub use mesh::ViewMesh;
pub use protocol::{ClientMessage, MessageError, frame_json, parse_message, positions_le_f32};
pub use server::{
    BodyFactory, Server, ServerHandle, ServerOptions, ServerStats, binding_warning, default_max_connections,
};

/// The page served at `GET /`: one HTML file with inline JavaScript and CSS (Canvas 2D, no
/// external URL).
pub const INDEX_HTML: &str = include_str!("../assets/index.html");
