//! Shared helpers: scenes, bodies, a server on a free port, a tiny HTTP client and a
//! WebSocket client that reads frames.

use std::io::{ErrorKind, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::sync::Arc;
use std::time::Duration;

use fibfluid_geometry::Vec3;
use fibfluid_interact::{FfmBody, Interactive, Method, Storage};
use fibfluid_interact::{ProbeOptions, build_body};
use fibfluid_scene::Scene;
use fibfluid_sim::Shape;
use fibfluid_viewer::{BodyFactory, Server, ServerHandle, ServerOptions, ViewMesh, ViewerError};
use tungstenite::{Message, WebSocket, stream::MaybeTlsStream};

/// The paper's sphere (icosphere level 2, N = 162, cap y > 0.8 fixed, gravity and a point
/// force as the base state).
pub fn sphere_path() -> &'static str {
    concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/scenes/sphere.toml")
}

/// A scene and its FFM body.
pub fn scene_body(path: &str, storage: Storage) -> (Scene, FfmBody) {
    let scene = Scene::load(path).expect("the scene loads");
    let opts = ProbeOptions { storage, max_memory_bytes: None, ..Default::default() };
    let body = build_body(&scene, &opts).expect("the body builds").body;
    (scene, body)
}

/// The sphere with an extra vertex at `unused` that no face uses written first in the file,
/// so file vertex `v + 1` is body vertex `v`: the protocol must speak the file's order.
/// Writes the mesh and the scene into `dir`; returns the scene's path.
pub fn sphere_with_unused_first_vertex(dir: &std::path::Path, unused: Vec3) -> String {
    let obj = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../fixtures/meshes/icosphere-2.obj"
    ))
    .unwrap();
    let mut out = format!("v {} {} {}\n", unused[0], unused[1], unused[2]);
    for line in obj.lines() {
        match line.strip_prefix("f ") {
            Some(rest) => {
                let shifted: Vec<String> =
                    rest.split_whitespace().map(|i| (i.parse::<usize>().unwrap() + 1).to_string()).collect();
                out.push_str(&format!("f {}\n", shifted.join(" ")));
            }
            None => out.push_str(&format!("{line}\n")),
        }
    }
    std::fs::create_dir_all(dir).unwrap();
    std::fs::write(dir.join("shifted.obj"), out).unwrap();
    let scene =
        std::fs::read_to_string(sphere_path()).unwrap().replace("../meshes/icosphere-2.obj", "shifted.obj");
    // The scene's point force names file vertex 3; keep it on the same point.
    let scene = scene.replace("vertex = 3", "vertex = 4");
    let path = dir.join("shifted.toml");
    std::fs::write(&path, scene).unwrap();
    path.to_string_lossy().into_owned()
}

/// A server of `body` (each client gets a clone), on a free port of 127.0.0.1.
pub fn serve(scene: &Scene, body: &FfmBody, max_clients: usize) -> ServerHandle {
    serve_with(scene, body, ServerOptions { max_clients, ..test_options() })
}

/// The options of [`serve`] (a free port of 127.0.0.1, the methods `ffm` and
/// `tsve-chainmail`).
pub fn test_options() -> ServerOptions {
    ServerOptions {
        port: 0,
        max_clients: 4,
        methods: vec![Method::Ffm, Method::TsveChainmail],
        ..Default::default()
    }
}

/// A server of `body` with the given options.
pub fn serve_with(scene: &Scene, body: &FfmBody, opts: ServerOptions) -> ServerHandle {
    let Shape::Surface(file) = &scene.shape else { panic!("a surface scene") };
    let mesh = ViewMesh::new(file, body).expect("mesh and body agree");
    let proto = body.clone();
    let factory: BodyFactory = Arc::new(move |method: Method| {
        if method == Method::Ffm {
            Ok(Box::new(proto.clone()) as Box<dyn Interactive + Send>)
        } else {
            Err(ViewerError::UnsupportedMethod { method: method.to_string(), available: "ffm".into() })
        }
    });
    Server::bind(opts).expect("binds a free port").spawn(mesh, factory)
}

/// `GET path`: (status line, headers, body).
pub fn http_get(addr: SocketAddr, path: &str) -> (String, String, Vec<u8>) {
    let mut s = TcpStream::connect(addr).expect("connects");
    write!(s, "GET {path} HTTP/1.1\r\nHost: {addr}\r\n\r\n").unwrap();
    let mut out = Vec::new();
    s.read_to_end(&mut out).expect("reads the answer");
    let end = out.windows(4).position(|w| w == b"\r\n\r\n").expect("a head");
    let head = String::from_utf8_lossy(&out[..end]).to_string();
    let (status, headers) = head.split_once("\r\n").unwrap_or((&head, ""));
    (status.to_string(), headers.to_string(), out[end + 4..].to_vec())
}

/// A WebSocket client.
pub struct Client {
    /// The socket.
    pub ws: WebSocket<MaybeTlsStream<TcpStream>>,
}

/// One frame: its text message and the decoded positions.
#[derive(Debug)]
pub struct Frame {
    pub frame: u64,
    pub reactions: Vec<(usize, Vec3)>,
    pub latency_us: f64,
    pub positions: Vec<Vec3>,
    /// The frame's `tools` (empty without a grasp or a tip).
    pub tools: Vec<serde_json::Value>,
    /// The result guards that fired on the frame (every frame carries the list).
    pub warnings: Vec<serde_json::Value>,
    /// The frame's `linearization` (null but on a two-rate body).
    pub linearization: serde_json::Value,
}

/// What the server sent next: a frame or an error text.
#[derive(Debug)]
pub enum Reply {
    Frame(Frame),
    Error(String),
}

impl Client {
    pub fn connect(addr: SocketAddr, query: &str) -> Self {
        let (ws, _) = tungstenite::connect(format!("ws://{addr}/ws{query}")).expect("the handshake succeeds");
        Self { ws }
    }

    pub fn send(&mut self, text: &str) {
        self.ws.send(Message::text(text.to_string())).expect("sends");
    }

    pub fn grab(&mut self, v: usize, to: Vec3) {
        self.send(&format!("{{\"grab\": {v}, \"to\": [{:e}, {:e}, {:e}]}}", to[0], to[1], to[2]));
    }

    /// The next error or frame (text message, then the binary positions).
    pub fn reply(&mut self) -> Reply {
        let text = loop {
            match self.ws.read().expect("a message") {
                Message::Text(t) => break t.to_string(),
                Message::Binary(_) => panic!("a binary message without its text message"),
                _ => continue,
            }
        };
        let v: serde_json::Value = serde_json::from_str(&text).expect("JSON from the server");
        if let Some(e) = v.get("error") {
            return Reply::Error(e.as_str().expect("an error text").to_string());
        }
        let bytes = loop {
            match self.ws.read().expect("the positions") {
                Message::Binary(b) => break b,
                Message::Text(t) => panic!("text {t} where the positions were due"),
                _ => continue,
            }
        };
        assert_eq!(bytes.len() % 12, 0, "3 N little-endian f32");
        let f: Vec<f32> = bytes.chunks_exact(4).map(|c| f32::from_le_bytes(c.try_into().unwrap())).collect();
        let positions = f.chunks_exact(3).map(|p| [p[0] as f64, p[1] as f64, p[2] as f64]).collect();
        let reactions = v["reactions"]
            .as_array()
            .expect("reactions")
            .iter()
            .map(|r| {
                let r = r.as_array().expect("[V, fx, fy, fz]");
                assert_eq!(r.len(), 4);
                (
                    r[0].as_u64().unwrap() as usize,
                    [r[1].as_f64().unwrap(), r[2].as_f64().unwrap(), r[3].as_f64().unwrap()],
                )
            })
            .collect();
        Reply::Frame(Frame {
            frame: v["frame"].as_u64().expect("frame"),
            reactions,
            latency_us: v["latency_us"].as_f64().expect("latency_us"),
            positions,
            tools: v["tools"].as_array().cloned().unwrap_or_default(),
            warnings: v["warnings"].as_array().cloned().expect("every frame lists its warnings"),
            linearization: v["linearization"].clone(),
        })
    }

    pub fn frame(&mut self) -> Frame {
        match self.reply() {
            Reply::Frame(f) => f,
            Reply::Error(e) => panic!("expected a frame, got the error {e}"),
        }
    }

    pub fn error(&mut self) -> String {
        match self.reply() {
            Reply::Error(e) => e,
            Reply::Frame(f) => panic!("expected an error, got frame {}", f.frame),
        }
    }
}

/// Largest distance between two lists of points.
pub fn max_dist(a: &[Vec3], b: &[Vec3]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(p, q)| ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt())
        .fold(0.0, f64::max)
}

/// How long a test waits for an answer that must come (it proves an answer at all, not
/// a speed).
pub const ANSWER_TIMEOUT: Duration = Duration::from_secs(20);

/// A connection to `addr` that reads with [`ANSWER_TIMEOUT`].
pub fn connect(addr: SocketAddr) -> TcpStream {
    let s = TcpStream::connect_timeout(&addr, ANSWER_TIMEOUT).expect("connects");
    s.set_read_timeout(Some(ANSWER_TIMEOUT)).unwrap();
    s.set_write_timeout(Some(ANSWER_TIMEOUT)).unwrap();
    s
}

/// Reads until the server closes (or a reset after an answer), within [`ANSWER_TIMEOUT`];
/// panics when nothing at all arrives in time.
pub fn read_answer(s: &mut TcpStream) -> String {
    let mut out = Vec::new();
    let mut buf = [0u8; 4096];
    loop {
        match s.read(&mut buf) {
            Ok(0) => break,
            Ok(n) => out.extend_from_slice(&buf[..n]),
            Err(e) if e.kind() == ErrorKind::Interrupted => {}
            Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {
                assert!(!out.is_empty(), "no answer within {ANSWER_TIMEOUT:?}");
                break;
            }
            Err(_) => break,
        }
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// Sends raw bytes as a request and returns the whole answer.
pub fn raw_request(addr: SocketAddr, bytes: &[u8]) -> String {
    let mut s = connect(addr);
    s.write_all(bytes).expect("sends the request");
    read_answer(&mut s)
}

/// The status line of an answer.
pub fn status_line(answer: &str) -> &str {
    answer.split("\r\n").next().unwrap_or("")
}

/// The body of an answer.
pub fn answer_body(answer: &str) -> &str {
    answer.split_once("\r\n\r\n").map_or("", |(_, b)| b)
}

/// A handshake request for `/ws` with the given extra header lines (each ending in
/// `\r\n`).
pub fn handshake(addr: SocketAddr, headers: &str) -> String {
    format!("GET /ws HTTP/1.1\r\nHost: {addr}\r\n{headers}\r\n")
}

/// The header lines of a valid handshake (the key of RFC 6455's example).
pub const GOOD_HANDSHAKE: &str = "Upgrade: websocket\r\nConnection: Upgrade\r\n\
    Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n";

/// A raw WebSocket connection after a valid handshake (101 checked).
pub fn raw_websocket(addr: SocketAddr) -> TcpStream {
    let mut s = connect(addr);
    s.write_all(handshake(addr, GOOD_HANDSHAKE).as_bytes()).unwrap();
    let mut head = Vec::new();
    let mut byte = [0u8; 1];
    while !head.ends_with(b"\r\n\r\n") {
        s.read_exact(&mut byte).expect("the handshake answer");
        head.push(byte[0]);
    }
    let head = String::from_utf8_lossy(&head);
    assert!(head.starts_with("HTTP/1.1 101 Switching Protocols\r\n"), "{head}");
    assert!(head.contains("Sec-WebSocket-Accept: s3pPLMBiTxaQ9kYGzzhZRbK+xOo=\r\n"), "{head}");
    s
}

/// A client frame: `first` is the first byte (FIN, RSV and opcode), the payload is masked
/// unless `masked` is false.
pub fn client_frame(first: u8, payload: &[u8], masked: bool) -> Vec<u8> {
    let mask_bit = if masked { 0x80 } else { 0 };
    let mut out = vec![first];
    match payload.len() {
        n if n < 126 => out.push(mask_bit | n as u8),
        n if n < 65536 => {
            out.push(mask_bit | 126);
            out.extend_from_slice(&(n as u16).to_be_bytes());
        }
        n => {
            out.push(mask_bit | 127);
            out.extend_from_slice(&(n as u64).to_be_bytes());
        }
    }
    let key = [0x37, 0xfa, 0x21, 0x3d];
    if masked {
        out.extend_from_slice(&key);
        out.extend(payload.iter().enumerate().map(|(i, b)| b ^ key[i % 4]));
    } else {
        out.extend_from_slice(payload);
    }
    out
}

/// A server frame: (opcode, payload), or `None` when the connection ends first.
pub fn server_frame(s: &mut TcpStream) -> Option<(u8, Vec<u8>)> {
    let mut h = [0u8; 2];
    s.read_exact(&mut h).ok()?;
    assert_eq!(h[1] & 0x80, 0, "server frames are not masked");
    let len = match h[1] & 0x7f {
        126 => {
            let mut b = [0u8; 2];
            s.read_exact(&mut b).ok()?;
            u16::from_be_bytes(b) as usize
        }
        127 => {
            let mut b = [0u8; 8];
            s.read_exact(&mut b).ok()?;
            u64::from_be_bytes(b) as usize
        }
        n => n as usize,
    };
    let mut payload = vec![0u8; len];
    s.read_exact(&mut payload).ok()?;
    Some((h[0] & 0x0f, payload))
}

/// Reads server frames up to a close frame: its (code, reason); `None` when the
/// connection ends without one.
pub fn close_frame(s: &mut TcpStream) -> Option<(u16, String)> {
    loop {
        let (opcode, payload) = server_frame(s)?;
        if opcode == 8 {
            assert!(payload.len() >= 2, "a close frame with a code");
            let code = u16::from_be_bytes([payload[0], payload[1]]);
            return Some((code, String::from_utf8_lossy(&payload[2..]).into_owned()));
        }
    }
}

/// Polls `done` every 20 ms for at most [`ANSWER_TIMEOUT`]; whether it came true.
pub fn eventually(mut done: impl FnMut() -> bool) -> bool {
    let start = std::time::Instant::now();
    while start.elapsed() < ANSWER_TIMEOUT {
        if done() {
            return true;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    done()
}
