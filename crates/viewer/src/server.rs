//! The server: one listener, routing by request head, one thread per connection.

use std::io::{ErrorKind, Read, Write};
use std::net::{IpAddr, Shutdown, SocketAddr, TcpListener, TcpStream, ToSocketAddrs};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use fibfluid_geometry::Vec3;
use fibfluid_interact::{FrameGuardError, FrameGuards};
use fibfluid_interact::{Interactive, Method, RigidMotion, ToolSet};
use fibfluid_sim::result_guards::ResultChecks;
use tungstenite::protocol::frame::coding::CloseCode;
use tungstenite::protocol::{CloseFrame, Role};
use tungstenite::{Message, WebSocket};

use crate::protocol::{ClientMessage, MessageError, frame_json, parse_message, positions_le_f32};
use crate::{INDEX_HTML, Result, ViewMesh, ViewerError, http};

/// Builds a new body for a client for one of the server's [`ServerOptions::methods`]; a
/// method it cannot build is [`ViewerError::UnsupportedMethod`].
pub type BodyFactory =
    Arc<dyn Fn(Method) -> std::result::Result<Box<dyn Interactive + Send>, ViewerError> + Send + Sync>;

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
    pub methods: Vec<Method>,
    /// Most connections open at once (requests being read or answered and WebSocket
    /// clients); one beyond is answered `503 Service Unavailable` and closed at once.
    /// Default: [`default_max_connections`].
    pub max_connections: usize,
    /// How long a connection may take to send its whole request head (an HTTP request or
    /// a WebSocket handshake); a slower one is answered `408 Request Timeout` and closed,
    /// which frees its place. 10 s by default.
    pub head_timeout: Duration,
    /// How long one write to a client may block (a client that does not read fills its
    /// socket's buffers); past it the client is dropped. 10 s by default.
    pub write_timeout: Duration,
}

impl Default for ServerOptions {
    fn default() -> Self {
        Self {
            host: "127.0.0.1".into(),
            port: 0,
            max_clients: 8,
            methods: vec![Method::Ffm],
            max_connections: default_max_connections(),
            head_timeout: Duration::from_secs(10),
            write_timeout: Duration::from_secs(10),
        }
    }
}

/// The default [`ServerOptions::max_connections`]: 256, or half the process's soft limit
/// of open files when that is lower (read from `/proc/self/limits`; each connection holds
/// one descriptor and the rest of the process needs some), at least 1.
pub fn default_max_connections() -> usize {
    let soft = std::fs::read_to_string("/proc/self/limits").ok().and_then(|text| {
        let line = text.lines().find(|l| l.starts_with("Max open files"))?;
        line["Max open files".len()..].split_whitespace().next()?.parse::<usize>().ok()
    });
    match soft {
        Some(n) => (n / 2).clamp(1, 256),
        None => 256,
    }
}

/// The warning due when a server listens on `addr`: `None` for a loopback address
/// (127.0.0.0/8, `::1`, or `::ffff:127.x.y.z`), otherwise a sentence saying that other
/// machines can reach a server without authentication or encryption.
pub fn binding_warning(addr: SocketAddr) -> Option<String> {
    let ip = match addr.ip() {
        IpAddr::V6(v6) => v6.to_ipv4_mapped().map(IpAddr::V4).unwrap_or(IpAddr::V6(v6)),
        v4 => v4,
    };
    if ip.is_loopback() {
        return None;
    }
    let reach = if ip.is_unspecified() {
        "every network interface of this machine".to_string()
    } else {
        format!("{ip}, which is not a loopback address")
    };
    Some(format!(
        "warning: the viewer listens on {addr} ({reach}): anyone who can reach this machine over the \
         network can connect, and there is no authentication or encryption; bind 127.0.0.1 unless the \
         network is trusted"
    ))
}

/// Counters of a running server, from [`ServerHandle::stats`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ServerStats {
    /// Connections open now (counted against [`ServerOptions::max_connections`]).
    pub connections: usize,
    /// WebSocket clients served now (counted against [`ServerOptions::max_clients`]).
    pub clients: usize,
    /// Connections answered 503 (or dropped when no thread could be started) since the
    /// start.
    pub refused: u64,
    /// Failed `accept` calls since the start (out of descriptors, for instance); each is
    /// followed by a pause of 10 ms to 0.5 s instead of an immediate retry.
    pub accept_errors: u64,
}

/// Largest client WebSocket message (bytes): the protocol's messages are a few dozen
/// bytes; a larger one is answered by a close frame with code 1009.
const MAX_MESSAGE: usize = 64 * 1024;
/// Most client messages applied to one frame.
const MAX_BATCH: usize = 4096;
/// First pause after a failed `accept`; it doubles with each failure in a row.
const MIN_ACCEPT_PAUSE: Duration = Duration::from_millis(10);
/// Longest pause after a failed `accept`.
const MAX_ACCEPT_PAUSE: Duration = Duration::from_millis(500);

impl Shared {
    /// The methods this server offers, comma separated.
    fn available(&self) -> String {
        self.opts.methods.iter().map(|m| m.to_string()).collect::<Vec<_>>().join(", ")
    }
}

struct Shared {
    mesh: ViewMesh,
    /// The result guards of every frame, in the body's vertex order (an error when the
    /// mesh does not describe a body: every client is then refused).
    guards: Result<FrameGuards>,
    mesh_json: String,
    info_json: String,
    factory: BodyFactory,
    opts: ServerOptions,
    clients: AtomicUsize,
    connections: AtomicUsize,
    refused: AtomicU64,
    accept_errors: AtomicU64,
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
    /// [`spawn`](Self::spawn). An address other than loopback is bound as asked; see
    /// [`warnings`](Self::warnings).
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

    /// What the operator should know about this server before it serves: empty when it
    /// listens on loopback only, else the [`binding_warning`] of its address.
    pub fn warnings(&self) -> Vec<String> {
        binding_warning(self.local_addr()).into_iter().collect()
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
            guards: body_guards(&mesh),
            mesh,
            info_json,
            factory,
            opts: self.opts,
            clients: AtomicUsize::new(0),
            connections: AtomicUsize::new(0),
            refused: AtomicU64::new(0),
            accept_errors: AtomicU64::new(0),
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

    /// The server's counters now.
    pub fn stats(&self) -> ServerStats {
        ServerStats {
            connections: self.shared.connections.load(Ordering::SeqCst),
            clients: self.shared.clients.load(Ordering::SeqCst),
            refused: self.shared.refused.load(Ordering::SeqCst),
            accept_errors: self.shared.accept_errors.load(Ordering::SeqCst),
        }
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
    let mut pause = Duration::ZERO;
    loop {
        let accepted = listener.accept();
        if shared.stop.load(Ordering::SeqCst) {
            break;
        }
        match accepted {
            Ok((stream, _)) => {
                pause = Duration::ZERO;
                admit(stream, shared);
            }
            Err(e) if e.kind() == ErrorKind::Interrupted => {}
            // Out of descriptors (EMFILE, ENFILE), of memory, or a connection that died in
            // the queue: retrying at once would spin without freeing anything; pause, a
            // little longer each time in a row.
            Err(_) => {
                shared.accept_errors.fetch_add(1, Ordering::SeqCst);
                pause = (pause * 2).clamp(MIN_ACCEPT_PAUSE, MAX_ACCEPT_PAUSE);
                std::thread::sleep(pause);
            }
        }
    }
}

/// Holds one place of [`ServerOptions::max_connections`]; gives it back when dropped.
struct ConnectionSlot(Arc<Shared>);

impl Drop for ConnectionSlot {
    fn drop(&mut self) {
        self.0.connections.fetch_sub(1, Ordering::SeqCst);
    }
}

/// Starts serving an accepted connection on its own thread, or answers 503 when the
/// server has [`ServerOptions::max_connections`] open.
fn admit(stream: TcpStream, shared: &Arc<Shared>) {
    let max = shared.opts.max_connections;
    if shared.connections.fetch_add(1, Ordering::SeqCst) >= max {
        shared.connections.fetch_sub(1, Ordering::SeqCst);
        shared.refused.fetch_add(1, Ordering::SeqCst);
        busy(stream, max);
        return;
    }
    let slot = ConnectionSlot(Arc::clone(shared));
    let spawned = std::thread::Builder::new().name("viewer-connection".into()).spawn(move || {
        let shared = Arc::clone(&slot.0);
        handle_connection(stream, &shared);
        drop(slot);
    });
    if spawned.is_err() {
        // The closure (the stream and the slot) is dropped: the connection closes.
        shared.refused.fetch_add(1, Ordering::SeqCst);
    }
}

/// Answers `503 Service Unavailable` from the accept loop without ever blocking it: the
/// socket is non-blocking and the answer fits in its empty send buffer.
fn busy(mut stream: TcpStream, max: usize) {
    let _ = stream.set_nonblocking(true);
    // Read what has already arrived: closing a socket with unread input resets the
    // connection, which can discard the answer before the client reads it.
    let mut sink = [0u8; 4096];
    let _ = stream.read(&mut sink);
    let body = format!("the viewer has {max} connections open (its limit); try again shortly\n");
    let answer = format!(
        "HTTP/1.1 503 Service Unavailable\r\nContent-Type: text/plain; charset=utf-8\r\nContent-Length: {}\r\n\
         Retry-After: 1\r\nConnection: close\r\n\r\n{body}",
        body.len()
    );
    let _ = stream.write_all(answer.as_bytes());
    let _ = stream.shutdown(Shutdown::Write);
}

fn handle_connection(mut stream: TcpStream, shared: &Shared) {
    let _ = stream.set_nodelay(true);
    let _ = stream.set_write_timeout(Some(shared.opts.write_timeout));
    let head = match http::read_head(&mut stream, shared.opts.head_timeout) {
        Ok(h) => h,
        Err(e) => {
            if let Some((status, reason)) = e.answer() {
                http::respond_text(&mut stream, status, "", &reason);
            }
            return;
        }
    };
    let (path, query) = head.target.split_once('?').unwrap_or((head.target.as_str(), ""));
    if path == "/ws" && head.values("upgrade").next().is_some() {
        let method = query
            .split('&')
            .find_map(|kv| kv.strip_prefix("method="))
            .map(str::to_string)
            .unwrap_or_else(|| shared.opts.methods.first().map(|m| m.to_string()).unwrap_or_default());
        match http::websocket_accept(&head) {
            Ok(accept) => upgrade(stream, head.rest, &accept, shared, &method),
            Err(r) => http::respond_text(&mut stream, r.status, r.headers, &r.reason),
        }
        return;
    }
    let head_only = head.method == "HEAD";
    if head.method != "GET" && !head_only {
        http::respond_text(
            &mut stream,
            "405 Method Not Allowed",
            "Allow: GET, HEAD\r\n",
            "only GET and HEAD",
        );
        return;
    }
    let (status, content_type, body) = match path {
        "/" | "/index.html" => ("200 OK", "text/html; charset=utf-8", INDEX_HTML.as_bytes()),
        "/mesh" => ("200 OK", "application/json", shared.mesh_json.as_bytes()),
        "/info" => ("200 OK", "application/json", shared.info_json.as_bytes()),
        "/ws" => ("400 Bad Request", "text/plain", &b"WebSocket upgrade expected\n"[..]),
        _ => ("404 Not Found", "text/plain", &b"not found\n"[..]),
    };
    http::respond(&mut stream, status, content_type, "", body, head_only);
}

/// Answers a checked handshake with `101 Switching Protocols` and serves the client.
fn upgrade(mut stream: TcpStream, rest: Vec<u8>, accept: &str, shared: &Shared, method: &str) {
    let answer = format!(
        "HTTP/1.1 101 Switching Protocols\r\nUpgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Accept: {accept}\r\n\r\n"
    );
    if stream.write_all(answer.as_bytes()).is_err() {
        return;
    }
    // A client may stay idle between drags: no read timeout once it is a WebSocket (the
    // number of clients is bounded by `max_clients`); writes keep their timeout.
    let _ = stream.set_read_timeout(None);
    let config = tungstenite::protocol::WebSocketConfig::default()
        .max_message_size(Some(MAX_MESSAGE))
        .max_frame_size(Some(MAX_MESSAGE));
    let ws = WebSocket::from_partially_read(stream, rest, Role::Server, Some(config));
    serve_client(ws, shared, method);
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

/// The result guards of `mesh`'s body: its rest shape and faces in the body's vertex order,
/// without the file's vertices that no face uses (the body has none of them).
fn body_guards(mesh: &ViewMesh) -> Result<FrameGuards> {
    let mismatch = |problem: String| ViewerError::Mismatch { problem };
    let count = mesh.positions.len();
    let rest = mesh
        .to_file
        .iter()
        .map(|&f| mesh.positions.get(f as usize).copied())
        .collect::<Option<Vec<Vec3>>>()
        .ok_or_else(|| mismatch(format!("a body vertex maps beyond the {count} vertices of the mesh")))?;
    let mut triangles = Vec::with_capacity(mesh.triangles.len());
    for t in &mesh.triangles {
        let body = t.map(|v| mesh.body_vertex(v as usize).map(|b| b as u32));
        match body {
            [Some(a), Some(b), Some(c)] => triangles.push([a, b, c]),
            _ => return Err(mismatch(format!("triangle {t:?} uses a vertex the body does not have"))),
        }
    }
    FrameGuards::new(&rest, &triangles).map_err(|e| mismatch(e.to_string()))
}

/// One client's body and the buffers of its frames.
struct Session<'a> {
    mesh: &'a ViewMesh,
    /// The result guards of the mesh, and what to check of this body's frames.
    guards: &'a FrameGuards,
    checks: ResultChecks,
    body: Box<dyn Interactive + Send>,
    tools: ToolSet,
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
            ClientMessage::Grasp { vertex, radius, to } => {
                let b = body_vertex(vertex)?;
                let rest = self.body.rest_positions()[b];
                let motion = RigidMotion::translation([to[0] - rest[0], to[1] - rest[1], to[2] - rest[2]]);
                self.tools.grasp(self.body.as_mut(), b, radius, motion)?;
            }
            ClientMessage::Press { centre, radius } => {
                self.tools.press(self.body.as_mut(), centre, radius)?
            }
            ClientMessage::Lift => self.tools.lift(self.body.as_mut())?,
            ClientMessage::Release { vertex } => {
                let b = body_vertex(vertex)?;
                if !self.tools.release(self.body.as_mut(), b)? {
                    self.body.release(b)?;
                }
            }
            ClientMessage::Reset => {
                self.tools.clear();
                self.body.release_all();
            }
        }
        Ok(true)
    }

    /// Computes the frame and checks it with the result guards; returns its text message
    /// (the binary one is in `self.bytes`). A non-finite answer is an error.
    fn frame(&mut self, start: Instant) -> std::result::Result<String, MessageError> {
        let tools = self.tools.frame(self.body.as_mut(), &self.mesh.to_file)?;
        for (b, p) in self.body.positions().iter().enumerate() {
            self.positions[self.mesh.to_file[b] as usize] = *p;
        }
        let to_file = |v: usize| self.mesh.to_file.get(v).map_or(v, |&f| f as usize);
        let warnings = self.guards.check(self.body.positions(), self.checks).map_err(|e| match e {
            FrameGuardError::NonFinite { vertex } => FrameGuardError::NonFinite { vertex: to_file(vertex) },
            other => other,
        })?;
        positions_le_f32(&self.positions, &mut self.bytes);
        let mut reactions: Vec<(usize, Vec3)> =
            self.body.reactions().iter().map(|&(b, f)| (self.mesh.to_file[b] as usize, f)).collect();
        reactions.sort_by_key(|r| r.0);
        let latency_us = start.elapsed().as_secs_f64() * 1e6;
        let latency_us = (latency_us * 10.0).round() / 10.0;
        let status = self.body.linearization();
        Ok(frame_json(self.body.frame(), &reactions, latency_us, &tools, &warnings, status.as_ref()))
    }
}

fn is_would_block(e: &tungstenite::Error) -> bool {
    matches!(e, tungstenite::Error::Io(io) if matches!(io.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut))
}

/// How a failed read ends the connection: the close frame owed to the client, if any
/// (`None`: the client is gone or the socket failed, nothing to say).
fn close_for(e: &tungstenite::Error) -> Option<CloseFrame> {
    use tungstenite::error::ProtocolError;
    let (code, reason) = match e {
        tungstenite::Error::Capacity(_) => (CloseCode::Size, "message too big (64 KiB at most)".to_string()),
        tungstenite::Error::Utf8(_) => (CloseCode::Invalid, "text message is not UTF-8".to_string()),
        tungstenite::Error::Protocol(ProtocolError::ResetWithoutClosingHandshake) => return None,
        tungstenite::Error::Protocol(p) => (CloseCode::Protocol, p.to_string().chars().take(100).collect()),
        _ => return None,
    };
    Some(CloseFrame { code, reason: reason.into() })
}

/// Ends a connection whose input cannot be read any further (a message too big, a
/// protocol violation): sends the close frame, then closes without waiting for the
/// client's (its input is no longer framed).
fn fail(mut ws: WebSocket<TcpStream>, frame: Option<CloseFrame>) {
    let _ = ws.get_mut().set_nonblocking(false);
    if let Some(frame) = frame {
        let _ = ws.close(Some(frame));
        let _ = ws.flush();
        http::linger_close(ws.get_mut());
    }
}

/// What one batch of client messages asks for.
struct Batch {
    /// When its first message was read (the frame's latency counts from there).
    start: Instant,
    /// A frame is due.
    due: bool,
    /// The client sent a close frame.
    closed: bool,
    /// The input failed: the connection ends (with this close frame, if any).
    failed: Option<Option<CloseFrame>>,
    /// Errors to send back, in order.
    errors: Vec<String>,
}

impl Batch {
    fn take(&mut self, session: &mut Session<'_>, read: tungstenite::Result<Message>) {
        match read {
            Ok(m) => {
                self.closed |= matches!(m, Message::Close(_));
                match session.apply(m) {
                    Ok(d) => self.due |= d,
                    Err(e) => self.errors.push(e.to_string()),
                }
            }
            Err(e) => self.failed = Some(close_for(&e)),
        }
    }
}

/// Reads one message (waiting for it), then whatever else has already arrived (at most
/// [`MAX_BATCH`] messages, so that a client sending without pause still gets frames).
fn read_batch(ws: &mut WebSocket<TcpStream>, session: &mut Session<'_>) -> Batch {
    let first = ws.read();
    let mut batch =
        Batch { start: Instant::now(), due: false, closed: false, failed: None, errors: Vec::new() };
    // The socket has no read timeout here: a would-block is a write (of a pending pong or
    // close) that timed out, and ends the connection like any failure.
    batch.take(session, first);
    if batch.closed || batch.failed.is_some() {
        return batch;
    }
    if ws.get_mut().set_nonblocking(true).is_err() {
        batch.failed = Some(None);
        return batch;
    }
    for _ in 1..MAX_BATCH {
        match ws.read() {
            Err(e) if is_would_block(&e) => break,
            next => batch.take(session, next),
        }
        if batch.closed || batch.failed.is_some() {
            break;
        }
    }
    if ws.get_mut().set_nonblocking(false).is_err() {
        batch.failed.get_or_insert(None);
    }
    batch
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
    let Some(method) = method.parse::<Method>().ok().filter(|m| shared.opts.methods.contains(m)) else {
        let e = ViewerError::UnsupportedMethod { method: method.to_string(), available: shared.available() };
        refuse(ws, &e.to_string(), CloseCode::Policy);
        return;
    };
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
    let guards = match &shared.guards {
        Ok(g) => g,
        Err(e) => {
            refuse(ws, &e.to_string(), CloseCode::Error);
            return;
        }
    };
    let mut session = Session {
        mesh: &shared.mesh,
        guards,
        checks: ResultChecks::for_frames(body.method(), body.linearization().is_some()),
        body,
        tools: ToolSet::default(),
        positions: shared.mesh.positions.clone(),
        bytes: Vec::new(),
    };
    loop {
        let batch = read_batch(&mut ws, &mut session);
        // Errors of the messages read before a failure are still answered.
        for e in &batch.errors {
            if ws.send(Message::text(error_json(e))).is_err() {
                return;
            }
        }
        if let Some(frame) = batch.failed {
            fail(ws, frame);
            return;
        }
        if batch.closed {
            // Let tungstenite finish the close handshake.
            while ws.read().is_ok() {}
            return;
        }
        if batch.due && !send_frame(&mut ws, &mut session, batch.start) {
            return;
        }
    }
}

/// Computes and sends one frame (or the body's error). `false`: the connection is done (a
/// write failed or timed out: the client does not read).
fn send_frame(ws: &mut WebSocket<TcpStream>, session: &mut Session<'_>, start: Instant) -> bool {
    match session.frame(start) {
        Ok(text) => {
            ws.write(Message::text(text)).is_ok() && ws.send(Message::binary(session.bytes.clone())).is_ok()
        }
        Err(e) => ws.send(Message::text(error_json(&e.to_string()))).is_ok(),
    }
}
