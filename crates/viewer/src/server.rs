//! The server: one listener, routing by request head, one thread per connection.

use std::io::{ErrorKind, Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream, ToSocketAddrs};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use fibfluid_geometry::Vec3;
use fibfluid_interact::{InteractError, Interactive};
use tungstenite::protocol::CloseFrame;
use tungstenite::protocol::frame::coding::CloseCode;
use tungstenite::{Message, WebSocket};

use crate::protocol::{ClientMessage, MessageError, frame_json, parse_message, positions_le_f32};
use crate::{INDEX_HTML, Result, ViewMesh};

/// Builds a new body for a client from a method name (`ffm`, `tsve-chainmail`, ...); an
/// unsupported method is [`ViewerError::UnsupportedMethod`].
pub type BodyFactory =
    Arc<dyn Fn(&str) -> std::result::Result<Box<dyn Interactive + Send>, ViewerError> + Send + Sync>;

/// What can go wrong while starting or running the viewer.
#[derive(Debug, thiserror::Error)]
pub enum ViewerError {
    /// The address cannot be resolved or bound.
    #[error("cannot listen on {addr}: {source}")]
    Bind {
        /// The address asked for.
        addr: String,
        /// Why.
        source: std::io::Error,
    },
    /// A method this server cannot build.
    #[error("method `{method}` is not available in this viewer (available: {available})")]
    UnsupportedMethod {
        /// The method asked for.
        method: String,
        /// The methods it can build, comma separated.
        available: String,
    },
    /// The body of a method could not be built.
    #[error("cannot build the {method} body: {source}")]
    Body {
        /// The method.
        method: String,
        /// Why.
        source: InteractError,
    },
    /// The body of a method could not be built for a reason of the method's own.
    #[error("cannot build the {method} body: {source}")]
    Build {
        /// The method.
        method: String,
        /// Why.
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// The mesh and the body do not describe the same surface.
    #[error("the mesh and the body disagree: {problem}")]
    Mismatch {
        /// What differs.
        problem: String,
    },
    /// Accepting a connection failed.
    #[error("viewer: {0}")]
    Io(#[from] std::io::Error),
}

/// Options of the server.
#[derive(Clone, Debug, PartialEq)]
pub struct ServerOptions {
    /// Address to bind (`127.0.0.1` by default: only this machine can connect).
    pub host: String,
    /// Port; 0 picks a free one.
    pub port: u16,
    /// Most clients served at once; a client beyond is refused with a message.
    pub max_clients: usize,
    /// Methods offered in the page's switch, the default first (the factory refuses those it
    /// cannot build).
    pub methods: Vec<String>,
}

impl Default for ServerOptions {
    fn default() -> Self {
        Self { host: "127.0.0.1".into(), port: 0, max_clients: 8, methods: vec!["ffm".into()] }
    }
}

/// Largest request head read (bytes); a longer one is answered 431.
const MAX_HEAD: usize = 16 * 1024;
/// Largest client WebSocket message (bytes): the protocol's messages are a few dozen
/// bytes; a larger one ends the connection.
const MAX_MESSAGE: usize = 64 * 1024;
/// Most client messages applied to one frame.
const MAX_BATCH: usize = 4096;
/// How long a connection may take to send its request head.
const HEAD_TIMEOUT: Duration = Duration::from_secs(10);

struct Shared {
    mesh: ViewMesh,
    mesh_json: String,
    info_json: String,
    factory: BodyFactory,
    opts: ServerOptions,
    clients: AtomicUsize,
    stop: AtomicBool,
}

/// A bound viewer server (not yet accepting). Binding comes first so that a port in use
/// is reported before a body is built (which can take a minute on a large mesh).
pub struct Server {
    listener: TcpListener,
    opts: ServerOptions,
}

/// A server running on a background thread.
pub struct ServerHandle {
    addr: SocketAddr,
    shared: Arc<Shared>,
    thread: Option<JoinHandle<()>>,
}

impl Server {
    /// Binds the listener. Nothing is served until [`run`](Self::run) or
    /// [`spawn`](Self::spawn).
    pub fn bind(opts: ServerOptions) -> Result<Self> {
        // An IPv6 literal needs brackets before the port.
        let addr = if opts.host.contains(':') && !opts.host.starts_with('[') {
            format!("[{}]:{}", opts.host, opts.port)
        } else {
            format!("{}:{}", opts.host, opts.port)
        };
        let bind_err = |source| ViewerError::Bind { addr: addr.clone(), source };
        let addrs: Vec<SocketAddr> = addr.to_socket_addrs().map_err(bind_err)?.collect();
        let listener = TcpListener::bind(&addrs[..]).map_err(bind_err)?;
        Ok(Self { listener, opts })
    }

    /// The bound address.
    pub fn local_addr(&self) -> SocketAddr {
        self.listener.local_addr().expect("a bound listener has an address")
    }

    /// The page's URL (`http://ADDR/`).
    pub fn url(&self) -> String {
        format!("http://{}/", self.local_addr())
    }

    fn shared(self, mesh: ViewMesh, factory: BodyFactory) -> (TcpListener, Arc<Shared>) {
        let info_json = serde_json::json!({
            "methods": self.opts.methods,
            "max_clients": self.opts.max_clients,
            "vertices": mesh.n_file_vertices(),
        })
        .to_string();
        let shared = Arc::new(Shared {
            mesh_json: mesh.to_json(),
            mesh,
            info_json,
            factory,
            opts: self.opts,
            clients: AtomicUsize::new(0),
            stop: AtomicBool::new(false),
        });
        (self.listener, shared)
    }

    /// Serves `mesh`, one body from `factory` per client, until the process ends (one
    /// thread per connection).
    pub fn run(self, mesh: ViewMesh, factory: BodyFactory) -> Result<()> {
        let (listener, shared) = self.shared(mesh, factory);
        accept_loop(&listener, &shared);
        Ok(())
    }

    /// Serves on a background thread.
    pub fn spawn(self, mesh: ViewMesh, factory: BodyFactory) -> ServerHandle {
        let addr = self.local_addr();
        let (listener, shared) = self.shared(mesh, factory);
        let thread_shared = Arc::clone(&shared);
        let thread = std::thread::spawn(move || accept_loop(&listener, &thread_shared));
        ServerHandle { addr, shared, thread: Some(thread) }
    }
}

impl ServerHandle {
    /// The bound address.
    pub fn local_addr(&self) -> SocketAddr {
        self.addr
    }

    /// The page's URL (`http://ADDR/`).
    pub fn url(&self) -> String {
        format!("http://{}/", self.addr)
    }

    /// Stops accepting connections (open connections run to their end).
    pub fn stop(mut self) {
        self.shutdown();
    }

    fn shutdown(&mut self) {
        self.shared.stop.store(true, Ordering::SeqCst);
        // Wake the blocking accept.
        let _ = TcpStream::connect_timeout(&self.addr, Duration::from_secs(1));
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for ServerHandle {
    fn drop(&mut self) {
        if self.thread.is_some() {
            self.shutdown();
        }
    }
}

fn accept_loop(listener: &TcpListener, shared: &Arc<Shared>) {
    for stream in listener.incoming() {
        if shared.stop.load(Ordering::SeqCst) {
            break;
        }
        let Ok(stream) = stream else { continue };
        let shared = Arc::clone(shared);
        std::thread::spawn(move || handle_connection(stream, &shared));
    }
}

/// The request line and the headers that matter for routing.
struct Head {
    len: usize,
    method: String,
    target: String,
    upgrade: bool,
}

/// Peeks at the request head without consuming it (so that a WebSocket handshake can read
/// it again). `Ok(None)`: the head is too long.
fn peek_head(stream: &TcpStream) -> std::io::Result<Option<Head>> {
    let mut buf = vec![0u8; MAX_HEAD];
    let start = Instant::now();
    let mut last = 0;
    loop {
        let n = stream.peek(&mut buf)?;
        if n == 0 {
            return Err(std::io::Error::new(ErrorKind::UnexpectedEof, "connection closed before a request"));
        }
        if let Some(end) = buf[..n].windows(4).position(|w| w == b"\r\n\r\n") {
            let text = String::from_utf8_lossy(&buf[..end]);
            let mut lines = text.split("\r\n");
            let mut first = lines.next().unwrap_or("").split_whitespace();
            let method = first.next().unwrap_or("").to_string();
            let target = first.next().unwrap_or("").to_string();
            let upgrade = lines.any(|l| {
                let mut kv = l.splitn(2, ':');
                let (k, v) = (kv.next().unwrap_or("").trim(), kv.next().unwrap_or("").trim());
                k.eq_ignore_ascii_case("upgrade") && v.eq_ignore_ascii_case("websocket")
            });
            return Ok(Some(Head { len: end + 4, method, target, upgrade }));
        }
        if n == MAX_HEAD {
            return Ok(None);
        }
        if start.elapsed() > HEAD_TIMEOUT {
            return Err(std::io::Error::new(ErrorKind::TimedOut, "request head too slow"));
        }
        if n == last {
            std::thread::sleep(Duration::from_millis(1));
        }
        last = n;
    }
}

fn respond(stream: &mut TcpStream, status: &str, content_type: &str, body: &[u8], head_only: bool) {
    let head = format!(
        "HTTP/1.1 {status}\r\nContent-Type: {content_type}\r\nContent-Length: {}\r\nCache-Control: no-store\r\nConnection: close\r\n\r\n",
        body.len()
    );
    let _ = stream.write_all(head.as_bytes());
    if !head_only {
        let _ = stream.write_all(body);
    }
    let _ = stream.flush();
    let _ = stream.shutdown(std::net::Shutdown::Write);
}

fn handle_connection(mut stream: TcpStream, shared: &Shared) {
    let _ = stream.set_read_timeout(Some(HEAD_TIMEOUT));
    let _ = stream.set_nodelay(true);
    let head = match peek_head(&stream) {
        Ok(Some(h)) => h,
        Ok(None) => {
            respond(
                &mut stream,
                "431 Request Header Fields Too Large",
                "text/plain",
                b"request head too long\n",
                false,
            );
            return;
        }
        Err(_) => return,
    };
    let (path, query) = head.target.split_once('?').unwrap_or((head.target.as_str(), ""));
    if path == "/ws" && head.upgrade {
        let method = query
            .split('&')
            .find_map(|kv| kv.strip_prefix("method="))
            .map(str::to_string)
            .unwrap_or_else(|| shared.opts.methods.first().cloned().unwrap_or_default());
        let _ = stream.set_read_timeout(None);
        let config = tungstenite::protocol::WebSocketConfig::default()
            .max_message_size(Some(MAX_MESSAGE))
            .max_frame_size(Some(MAX_MESSAGE));
        if let Ok(ws) = tungstenite::accept_with_config(stream, Some(config)) {
            serve_client(ws, shared, &method);
        }
        return;
    }
    // Consume the head (requests without a body are all this server answers).
    let mut sink = vec![0u8; head.len];
    if stream.read_exact(&mut sink).is_err() {
        return;
    }
    let head_only = head.method == "HEAD";
    if head.method != "GET" && !head_only {
        respond(&mut stream, "405 Method Not Allowed", "text/plain", b"only GET\n", false);
        return;
    }
    match path {
        "/" | "/index.html" => {
            respond(&mut stream, "200 OK", "text/html; charset=utf-8", INDEX_HTML.as_bytes(), head_only)
        }
        "/mesh" => respond(&mut stream, "200 OK", "application/json", shared.mesh_json.as_bytes(), head_only),
        "/info" => respond(&mut stream, "200 OK", "application/json", shared.info_json.as_bytes(), head_only),
        "/ws" => {
            respond(&mut stream, "400 Bad Request", "text/plain", b"WebSocket upgrade expected\n", head_only)
        }
        _ => respond(&mut stream, "404 Not Found", "text/plain", b"not found\n", head_only),
    }
}

fn error_json(text: &str) -> String {
    serde_json::json!({ "error": text }).to_string()
}

/// Leaves the client count when the client goes.
struct ClientSlot<'a>(&'a AtomicUsize);

impl Drop for ClientSlot<'_> {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::SeqCst);
    }
}

fn refuse(mut ws: WebSocket<TcpStream>, text: &str, code: CloseCode) {
    let _ = ws.send(Message::text(error_json(text)));
    let reason: String = text.chars().take(100).collect();
    let _ = ws.close(Some(CloseFrame { code, reason: reason.into() }));
    // Read until the close handshake completes (or the client goes).
    let _ = ws.get_mut().set_read_timeout(Some(Duration::from_secs(2)));
    while ws.read().is_ok() {}
}

/// One client's body and the buffers of its frames.
struct Session<'a> {
    mesh: &'a ViewMesh,
    body: Box<dyn Interactive + Send>,
    positions: Vec<Vec3>,
    bytes: Vec<u8>,
}

impl Session<'_> {
    /// Applies one message to the pending holds. `Ok(true)`: a frame is due.
    fn apply(&mut self, msg: Message) -> std::result::Result<bool, MessageError> {
        let text = match msg {
            Message::Text(t) => t,
            Message::Binary(_) => return Err(MessageError::Binary),
            _ => return Ok(false),
        };
        let count = self.mesh.n_file_vertices();
        let body_vertex = |vertex: usize| {
            if vertex >= count {
                return Err(MessageError::UnknownVertex { vertex, count });
            }
            self.mesh.body_vertex(vertex).ok_or(MessageError::UnusedVertex { vertex })
        };
        match parse_message(text.as_str())? {
            ClientMessage::Grab { vertex, to } => {
                let b = body_vertex(vertex)?;
                if self.body.is_fixed(b) {
                    return Err(MessageError::FixedVertex { vertex });
                }
                let rest = self.mesh.positions[vertex];
                self.body.grab(b, [to[0] - rest[0], to[1] - rest[1], to[2] - rest[2]])?;
            }
            ClientMessage::Release { vertex } => self.body.release(body_vertex(vertex)?)?,
            ClientMessage::Reset => self.body.release_all(),
        }
        Ok(true)
    }

    /// Computes the frame; returns its text message (the binary one is in `self.bytes`).
    fn frame(&mut self, start: Instant) -> std::result::Result<String, MessageError> {
        self.body.update()?;
        for (b, p) in self.body.positions().iter().enumerate() {
            self.positions[self.mesh.to_file[b] as usize] = *p;
        }
        positions_le_f32(&self.positions, &mut self.bytes);
        let mut reactions: Vec<(usize, Vec3)> =
            self.body.reactions().iter().map(|&(b, f)| (self.mesh.to_file[b] as usize, f)).collect();
        reactions.sort_by_key(|r| r.0);
        let latency_us = start.elapsed().as_secs_f64() * 1e6;
        Ok(frame_json(self.body.frame(), &reactions, (latency_us * 10.0).round() / 10.0))
    }
}

fn is_would_block(e: &tungstenite::Error) -> bool {
    matches!(e, tungstenite::Error::Io(io) if io.kind() == ErrorKind::WouldBlock)
}

fn serve_client(mut ws: WebSocket<TcpStream>, shared: &Shared, method: &str) {
    let max = shared.opts.max_clients;
    if shared.clients.fetch_add(1, Ordering::SeqCst) >= max {
        shared.clients.fetch_sub(1, Ordering::SeqCst);
        let text = format!("the viewer is full ({max} clients at most); try again later");
        refuse(ws, &text, CloseCode::Again);
        return;
    }
    let _slot = ClientSlot(&shared.clients);
    let body = match (shared.factory)(method) {
        Ok(b) if b.n_vertices() == shared.mesh.to_file.len() => b,
        Ok(b) => {
            let e = ViewerError::Mismatch {
                problem: format!(
                    "the body has {} vertices, the mesh {}",
                    b.n_vertices(),
                    shared.mesh.to_file.len()
                ),
            };
            refuse(ws, &e.to_string(), CloseCode::Error);
            return;
        }
        Err(e) => {
            refuse(ws, &e.to_string(), CloseCode::Policy);
            return;
        }
    };
    let mut session =
        Session { mesh: &shared.mesh, body, positions: shared.mesh.positions.clone(), bytes: Vec::new() };
    let mut errors: Vec<String> = Vec::new();
    loop {
        let first = match ws.read() {
            Ok(m) => m,
            Err(e) if is_would_block(&e) => continue,
            Err(_) => return,
        };
        let start = Instant::now();
        let mut due = false;
        let mut closed = matches!(first, Message::Close(_));
        match session.apply(first) {
            Ok(d) => due |= d,
            Err(e) => errors.push(e.to_string()),
        }
        // Coalesce: apply whatever else has arrived (at most MAX_BATCH messages, so that a
        // client sending without pause still gets frames); the last state wins.
        if !closed && ws.get_mut().set_nonblocking(true).is_ok() {
            for _ in 1..MAX_BATCH {
                match ws.read() {
                    Ok(m) => {
                        closed |= matches!(m, Message::Close(_));
                        match session.apply(m) {
                            Ok(d) => due |= d,
                            Err(e) => errors.push(e.to_string()),
                        }
                    }
                    Err(e) if is_would_block(&e) => break,
                    Err(_) => {
                        closed = true;
                        break;
                    }
                }
            }
            if ws.get_mut().set_nonblocking(false).is_err() {
                return;
            }
        }
        for e in errors.drain(..) {
            if ws.send(Message::text(error_json(&e))).is_err() {
                return;
            }
        }
        if closed {
            // Let tungstenite finish the close handshake.
            while ws.read().is_ok() {}
            return;
        }
        if due {
            match session.frame(start) {
                Ok(text) => {
                    if ws.write(Message::text(text)).is_err()
                        || ws.send(Message::binary(session.bytes.clone())).is_err()
                    {
                        return;
                    }
                }
                Err(e) => {
                    if ws.send(Message::text(error_json(&e.to_string()))).is_err() {
                        return;
                    }
                }
            }
        }
    }
}
