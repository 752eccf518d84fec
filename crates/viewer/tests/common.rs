//! Shared helpers: scenes, bodies, a server on a free port, a tiny HTTP client and a
//! WebSocket client that reads frames.

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::sync::Arc;

use fibfluid::geometry::Vec3;
use fibfluid::interact::{FfmBody, Interactive, Storage};
use fibfluid::interact::{ProbeOptions, build_body};
use fibfluid::{Scene, Shape};
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
    let opts = ProbeOptions { storage, max_memory_bytes: None };
    let body = build_body(&scene, &opts).expect("the body builds").body;
    (scene, body)
}

/// A server of `body` (each client gets a clone), on a free port of 127.0.0.1.
pub fn serve(scene: &Scene, body: &FfmBody, max_clients: usize) -> ServerHandle {
    let Shape::Surface(file) = &scene.shape else { panic!("a surface scene") };
    let mesh = ViewMesh::new(file, body).expect("mesh and body agree");
    let proto = body.clone();
    let factory: BodyFactory = Arc::new(move |name: &str| {
        if name == "ffm" {
            Ok(Box::new(proto.clone()) as Box<dyn Interactive + Send>)
        } else {
            Err(ViewerError::UnsupportedMethod { method: name.to_string(), available: "ffm".into() })
        }
    });
    let opts = ServerOptions {
        port: 0,
        max_clients,
        methods: vec!["ffm".into(), "tsve-chainmail".into()],
        ..Default::default()
    };
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
