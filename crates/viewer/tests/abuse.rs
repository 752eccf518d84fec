//! Hostile clients: too many connections, idle and slow request heads, malformed requests
//! and handshakes, oversized and invalid WebSocket frames, many clients at once, a client
//! that never reads. Every test talks to 127.0.0.1 only and bounds its waits by
//! `ANSWER_TIMEOUT` (a proof that an answer came at all, never a speed).

use std::io::{ErrorKind, Write};
use std::net::{SocketAddr, TcpStream};
use std::time::Duration;

use fibfluid_interact::{FfmBody, Storage};
use fibfluid_scene::Scene;
use fibfluid_viewer::{ServerHandle, ServerOptions, binding_warning};
use tungstenite::Message;
use tungstenite::protocol::frame::coding::CloseCode;

use crate::common::{
    Client, GOOD_HANDSHAKE, answer_body, client_frame, close_frame, connect, eventually, handshake,
    raw_request, raw_websocket, read_answer, scene_body, serve_with, sphere_path, status_line, test_options,
};

fn sphere() -> (Scene, FfmBody) {
    scene_body(sphere_path(), Storage::F64)
}

fn server(opts: ServerOptions) -> ServerHandle {
    let (scene, body) = sphere();
    serve_with(&scene, &body, opts)
}

/// `GET /info` until it is answered 200 (a bounded number of tries).
fn answers_again(addr: SocketAddr) -> bool {
    eventually(|| status_line(&raw_request(addr, b"GET /info HTTP/1.1\r\n\r\n")) == "HTTP/1.1 200 OK")
}

#[test]
fn connections_beyond_the_cap_are_answered_503() {
    // A head timeout far longer than the test: the 503 cannot come from idle sockets
    // timing out.
    let opts = ServerOptions { max_connections: 4, head_timeout: Duration::from_secs(600), ..test_options() };
    let server = server(opts);
    let addr = server.local_addr();
    let idle: Vec<TcpStream> = (0..4).map(|_| connect(addr)).collect();
    assert!(eventually(|| server.stats().connections == 4), "{:?}", server.stats());

    let answer = raw_request(addr, b"GET /info HTTP/1.1\r\n\r\n");
    assert_eq!(status_line(&answer), "HTTP/1.1 503 Service Unavailable");
    assert!(answer.contains("Retry-After: 1\r\n"));
    assert!(answer_body(&answer).contains("4 connections open"), "{answer}");
    // An idle extra connection is answered too, without sending anything.
    assert_eq!(status_line(&read_answer(&mut connect(addr))), "HTTP/1.1 503 Service Unavailable");
    assert!(server.stats().refused >= 2);

    drop(idle);
    assert!(answers_again(addr), "served again once the idle connections close");
    assert!(eventually(|| server.stats().connections == 0));
}

#[test]
fn idle_connections_time_out_and_free_their_places() {
    let opts =
        ServerOptions { max_connections: 4, head_timeout: Duration::from_millis(300), ..test_options() };
    let server = server(opts);
    let addr = server.local_addr();
    let mut idle: Vec<TcpStream> = (0..4).map(|_| connect(addr)).collect();
    // Each idle connection is told why it is closed...
    for s in &mut idle {
        let answer = read_answer(s);
        assert_eq!(status_line(&answer), "HTTP/1.1 408 Request Timeout", "{answer}");
    }
    // ...and the server answers again while the clients still hold their sockets open.
    assert!(answers_again(addr));
    assert_eq!(server.stats().accept_errors, 0);
}

#[test]
fn a_slowloris_head_times_out_as_a_whole() {
    let opts = ServerOptions { head_timeout: Duration::from_millis(500), ..test_options() };
    let server = server(opts);
    let mut s = connect(server.local_addr());
    let mut dripper = s.try_clone().unwrap();
    // One byte every 50 ms, each well within the head timeout, for at most 10 s.
    let drip = std::thread::spawn(move || {
        let _ = dripper.write_all(b"GET / HTTP/1.1\r\nX-Slow: ");
        for _ in 0..200 {
            if dripper.write_all(b"a").is_err() {
                return;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
    });
    let answer = read_answer(&mut s);
    assert_eq!(status_line(&answer), "HTTP/1.1 408 Request Timeout", "{answer}");
    drop(s);
    drip.join().unwrap();
}

#[test]
fn malformed_requests_get_400_with_a_reason() {
    let server = server(test_options());
    let addr = server.local_addr();
    for (request, status, reason) in [
        (&b"GARBAGE\r\n\r\n"[..], "400 Bad Request", "malformed request line"),
        (b"GET /\r\n\r\n", "400 Bad Request", "malformed request line"),
        (b"GET / HTTP/1.1 extra\r\n\r\n", "400 Bad Request", "malformed request line"),
        (b"GET http://evil/ HTTP/1.1\r\n\r\n", "400 Bad Request", "starting with `/`"),
        (b"G(T / HTTP/1.1\r\n\r\n", "400 Bad Request", "not a token"),
        (b"GET / HTTP/2.0\r\n\r\n", "505 HTTP Version Not Supported", "HTTP/2.0 is not supported"),
        (b"GET / HTTP/1.1\r\nno colon here\r\n\r\n", "400 Bad Request", "header line 1 (no `:`)"),
        (b"GET / HTTP/1.1\r\nA: b\r\n folded\r\n\r\n", "400 Bad Request", "header line 2"),
        (b"\xff\xfe\x00\x01 / HTTP/1.1\r\n\r\n", "400 Bad Request", "not UTF-8"),
        (b"POST / HTTP/1.1\r\nContent-Length: 5\r\n\r\nhello", "405 Method Not Allowed", "only GET and HEAD"),
    ] {
        let answer = raw_request(addr, request);
        assert_eq!(
            status_line(&answer),
            format!("HTTP/1.1 {status}"),
            "{}",
            String::from_utf8_lossy(request)
        );
        let body = answer_body(&answer);
        assert!(body.contains(reason) && body.lines().count() == 1, "{body:?}");
    }
    // Lenient line endings are still a request.
    assert_eq!(status_line(&raw_request(addr, b"GET /info HTTP/1.0\n\n")), "HTTP/1.1 200 OK");
    // HEAD: the head only.
    let answer = raw_request(addr, b"HEAD /info HTTP/1.1\r\n\r\n");
    assert_eq!(status_line(&answer), "HTTP/1.1 200 OK");
    assert_eq!(answer_body(&answer), "");
}

#[test]
fn huge_heads_get_431() {
    let server = server(test_options());
    let addr = server.local_addr();
    let long = format!("GET / HTTP/1.1\r\nX-Big: {}\r\n\r\n", "a".repeat(20 * 1024));
    let answer = raw_request(addr, long.as_bytes());
    assert_eq!(status_line(&answer), "HTTP/1.1 431 Request Header Fields Too Large", "{answer}");
    // A head that never ends is cut at the limit, not read forever.
    let mut s = connect(addr);
    let mut writer = s.try_clone().unwrap();
    let flood = std::thread::spawn(move || {
        let _ = writer.write_all(b"GET / HTTP/1.1\r\nX-Endless: ");
        let chunk = [b'a'; 4096];
        for _ in 0..4096 {
            if writer.write_all(&chunk).is_err() {
                return;
            }
        }
    });
    let answer = read_answer(&mut s);
    assert_eq!(status_line(&answer), "HTTP/1.1 431 Request Header Fields Too Large");
    drop(s);
    flood.join().unwrap();
    let many: String = (0..150).map(|i| format!("X-{i}: y\r\n")).collect();
    let answer = raw_request(addr, format!("GET / HTTP/1.1\r\n{many}\r\n").as_bytes());
    assert_eq!(status_line(&answer), "HTTP/1.1 431 Request Header Fields Too Large");
    assert!(answer_body(&answer).contains("too many header lines"));
    assert!(answers_again(addr));
}

#[test]
fn bad_handshakes_get_426_or_400() {
    let server = server(test_options());
    let addr = server.local_addr();
    let key = "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n";
    let upgrade = "Upgrade: websocket\r\nConnection: Upgrade\r\n";
    for version in ["Sec-WebSocket-Version: 8\r\n", "Sec-WebSocket-Version: 14\r\n", ""] {
        let answer = raw_request(addr, handshake(addr, &format!("{upgrade}{key}{version}")).as_bytes());
        assert_eq!(status_line(&answer), "HTTP/1.1 426 Upgrade Required", "{version}");
        assert!(answer.contains("\r\nSec-WebSocket-Version: 13\r\n"), "{answer}");
        assert!(answer_body(&answer).contains("unsupported Sec-WebSocket-Version"));
    }
    let v13 = "Sec-WebSocket-Version: 13\r\n";
    for (headers, reason) in [
        (format!("{upgrade}{v13}"), "exactly one Sec-WebSocket-Key"),
        (format!("{upgrade}{v13}Sec-WebSocket-Key: short\r\n"), "16 bytes in base64"),
        (format!("{upgrade}{v13}{key}{key}"), "exactly one Sec-WebSocket-Key"),
        (format!("Upgrade: websocket\r\n{v13}{key}"), "`Connection: Upgrade`"),
        (format!("Upgrade: h2c\r\nConnection: Upgrade\r\n{v13}{key}"), "`Upgrade: websocket`"),
    ] {
        let answer = raw_request(addr, handshake(addr, &headers).as_bytes());
        assert_eq!(status_line(&answer), "HTTP/1.1 400 Bad Request", "{headers}");
        let body = answer_body(&answer);
        assert!(body.contains(reason) && body.lines().count() == 1, "{headers}: {body:?}");
    }
    let post = format!("POST /ws HTTP/1.1\r\n{GOOD_HANDSHAKE}\r\n");
    assert!(answer_body(&raw_request(addr, post.as_bytes())).contains("is a GET request"));
    let old = format!("GET /ws HTTP/1.0\r\n{GOOD_HANDSHAKE}\r\n");
    assert!(answer_body(&raw_request(addr, old.as_bytes())).contains("needs HTTP/1.1"));
    // The good handshake (RFC 6455's example key) is accepted; a first message sent with
    // the handshake is read.
    let mut s = raw_websocket(addr);
    s.write_all(&client_frame(0x81, br#"{"reset": true}"#, true)).unwrap();
    let (opcode, text) = crate::common::server_frame(&mut s).expect("a frame");
    assert_eq!(opcode, 1);
    assert!(String::from_utf8_lossy(&text).contains("\"frame\""));
}

#[test]
fn a_message_too_big_is_closed_with_1009() {
    let server = server(test_options());
    let addr = server.local_addr();
    // One frame over the limit (tungstenite as the client).
    let mut c = Client::connect(addr, "");
    c.ws.send(Message::text("x".repeat(100 * 1024))).unwrap();
    match c.ws.read() {
        Ok(Message::Close(Some(f))) => {
            assert_eq!(f.code, CloseCode::Size);
            assert!(f.reason.contains("too big"), "{}", f.reason);
        }
        other => panic!("expected a close frame with code 1009, got {other:?}"),
    }
    // Frames under the limit whose message is over it.
    let mut s = raw_websocket(addr);
    let part = vec![b'x'; 60 * 1024];
    s.write_all(&client_frame(0x01, &part, true)).unwrap();
    s.write_all(&client_frame(0x00, &part, true)).unwrap();
    let (code, reason) = close_frame(&mut s).expect("a close frame before the end");
    assert_eq!(code, 1009, "{reason}");
    // The server closes the connection after it.
    assert!(crate::common::server_frame(&mut s).is_none());
    assert!(eventually(|| server.stats().clients == 0));
}

#[test]
fn protocol_violations_are_closed_with_their_code() {
    let server = server(test_options());
    let addr = server.local_addr();
    for (bytes, code, what) in [
        (client_frame(0xf1, b"", true), 1002, "reserved bits"),
        (client_frame(0x81, b"hi", false), 1002, "an unmasked client frame"),
        (client_frame(0x83, b"??", true), 1002, "an unknown opcode"),
        (client_frame(0x80, b"xx", true), 1002, "a continuation without a start"),
        (client_frame(0x09, b"", true), 1002, "a fragmented ping"),
        (client_frame(0x81, &[0xc3, 0x28], true), 1007, "text that is not UTF-8"),
    ] {
        let mut s = raw_websocket(addr);
        s.write_all(&bytes).unwrap();
        let (got, reason) = close_frame(&mut s).unwrap_or_else(|| panic!("{what}: no close frame"));
        assert_eq!(got, code, "{what}: {reason}");
        assert!(!reason.is_empty(), "{what}: a reason");
    }
    // Raw garbage after the handshake: the connection ends one way or another and the
    // server serves others.
    let mut s = raw_websocket(addr);
    let mut x: u32 = 12345;
    let garbage: Vec<u8> = (0..4096)
        .map(|_| {
            x = x.wrapping_mul(1_103_515_245).wrapping_add(12345);
            (x >> 16) as u8
        })
        .collect();
    let _ = s.write_all(&garbage);
    let mut c = Client::connect(addr, "");
    c.send(r#"{"reset": true}"#);
    c.frame();
}

#[test]
fn binary_garbage_messages_get_errors_and_the_connection_stays_open() {
    let server = server(test_options());
    let mut c = Client::connect(server.local_addr(), "");
    let mut x: u64 = 7;
    for len in [0, 1, 125, 126, 65535, 64 * 1024] {
        let garbage: Vec<u8> = (0..len)
            .map(|_| {
                x = x.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
                (x >> 56) as u8
            })
            .collect();
        c.ws.send(Message::binary(garbage)).unwrap();
        assert!(c.error().contains("binary messages are not part of the protocol"), "{len}");
    }
    c.send(r#"{"reset": true}"#);
    c.frame();
}

#[test]
fn many_clients_at_once_are_all_served() {
    let server = server(ServerOptions { max_clients: 8, ..test_options() });
    let addr = server.local_addr();
    let http: Vec<_> = (0..48)
        .map(|_| {
            std::thread::spawn(move || {
                status_line(&raw_request(addr, b"GET /info HTTP/1.1\r\n\r\n")).to_string()
            })
        })
        .collect();
    let ws: Vec<_> = (0..8)
        .map(|_| {
            std::thread::spawn(move || {
                let mut c = Client::connect(addr, "");
                for _ in 0..5 {
                    c.send(r#"{"reset": true}"#);
                    c.frame();
                }
            })
        })
        .collect();
    for t in http {
        assert_eq!(t.join().unwrap(), "HTTP/1.1 200 OK");
    }
    for t in ws {
        t.join().unwrap();
    }
    assert!(eventually(|| server.stats().connections == 0), "{:?}", server.stats());
    assert_eq!(server.stats().refused, 0);
}

#[test]
fn a_client_that_never_reads_is_dropped_without_blocking_others() {
    let opts = ServerOptions { max_clients: 2, write_timeout: Duration::from_millis(500), ..test_options() };
    let server = server(opts);
    let addr = server.local_addr();
    // Sends grabs (each answered by ~2 KB of frame) and never reads, until the server
    // drops it or 60 s pass.
    let mut stuck = raw_websocket(addr);
    stuck.set_write_timeout(Some(Duration::from_millis(200))).unwrap();
    let grab = client_frame(0x81, br#"{"grab": 3, "to": [0, -1, 0]}"#, true);
    let flood = std::thread::spawn(move || {
        let start = std::time::Instant::now();
        while start.elapsed() < Duration::from_secs(60) {
            match stuck.write_all(&grab) {
                Ok(()) => std::thread::sleep(Duration::from_micros(200)),
                Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {}
                Err(_) => return true,
            }
        }
        false
    });
    assert!(eventually(|| server.stats().clients == 1));
    // Another client is served while the first one's frames pile up.
    let mut c = Client::connect(addr, "");
    for _ in 0..5 {
        c.send(r#"{"reset": true}"#);
        c.frame();
    }
    assert!(flood.join().unwrap(), "the server drops a client that does not read");
    assert!(eventually(|| server.stats().clients == 1), "{:?}", server.stats());
    c.send(r#"{"reset": true}"#);
    c.frame();
}

#[test]
fn binding_anything_but_loopback_warns() {
    for quiet in ["127.0.0.1:8765", "127.3.2.1:80", "[::1]:8765", "[::ffff:127.0.0.1]:1"] {
        assert_eq!(binding_warning(quiet.parse().unwrap()), None, "{quiet}");
    }
    for (loud, expected) in [
        ("0.0.0.0:8765", "every network interface"),
        ("[::]:8765", "every network interface"),
        ("192.168.1.20:8765", "192.168.1.20, which is not a loopback address"),
        ("[2001:db8::1]:8765", "not a loopback address"),
    ] {
        let w = binding_warning(loud.parse().unwrap()).unwrap_or_else(|| panic!("{loud}: a warning"));
        assert!(w.contains(expected) && w.contains("no authentication"), "{w}");
    }
    let bound = fibfluid_viewer::Server::bind(test_options()).unwrap();
    assert!(bound.warnings().is_empty(), "127.0.0.1 is quiet");
}

/// A press from below the sphere's lowest vertex, `depth` into it (radius 0.6).
fn press_from_below(body: &FfmBody, depth: f64) -> String {
    use fibfluid_interact::Interactive;
    let r = body.rest_positions();
    let low = r.iter().copied().min_by(|a, b| a[1].total_cmp(&b[1])).unwrap();
    let c = [low[0], low[1] - 0.6 + depth, low[2]];
    format!(r#"{{"press": [{:e}, {:e}, {:e}], "radius": 0.6}}"#, c[0], c[1], c[2])
}

#[test]
fn a_non_finite_tip_centre_is_named_as_the_tip_centre() {
    let server = server(test_options());
    let mut c = Client::connect(server.local_addr(), "");
    for msg in [r#"{"press": [0, "NaN", 0], "radius": 0.3}"#, r#"{"press": [null, 0, 0], "radius": 0.3}"#] {
        c.send(msg);
        let e = c.error();
        assert!(e.contains("the tip's centre has a non-finite component"), "{msg}: {e}");
        assert!(!e.contains("vertex"), "{msg}: no vertex is involved: {e}");
    }
    c.send(r#"{"reset": true}"#);
    assert!(c.frame().tools.is_empty(), "the refused presses left no tip");
}

#[test]
fn a_refused_press_keeps_the_working_tip() {
    let (scene, body) = sphere();
    let server = serve_with(&scene, &body, test_options());
    let mut c = Client::connect(server.local_addr(), "");
    let press = press_from_below(&body, 0.1);
    c.send(&press);
    let working = c.frame();
    assert_eq!(working.tools.len(), 1, "{:?}", working.tools);
    assert!(working.tools[0]["contacts"].as_u64().unwrap() > 0, "{:?}", working.tools);
    for bad in [r#"{"press": [0, -1, 0], "radius": 50}"#, r#"{"press": [0, -1, 0], "radius": 1e308}"#] {
        c.send(bad);
        let e = c.error();
        assert!(e.contains("radius"), "{bad}: {e}");
    }
    // A message that changes no tool brings the next frame (the release of a free vertex
    // at the top, far from the tip, that nothing holds): the tip is still there.
    let top = {
        use fibfluid_interact::Interactive;
        let r = body.rest_positions();
        (0..r.len()).filter(|&v| !body.is_fixed(v)).max_by(|&a, &b| r[a][1].total_cmp(&r[b][1])).unwrap()
    };
    c.send(&format!(r#"{{"release": {top}}}"#));
    let after = c.frame();
    assert_eq!(after.tools.len(), 1, "the refused presses removed the tip: {:?}", after.tools);
    for key in ["press", "radius", "contacts"] {
        assert_eq!(after.tools[0][key], working.tools[0][key], "{key}");
    }
    let moved = crate::common::max_dist(&after.positions, &working.positions);
    assert!(moved <= 1e-6, "the surface moved by {moved:e} after refused presses");
}

#[test]
fn a_tip_in_the_fixed_cap_names_the_fixed_vertices() {
    let server = server(test_options());
    let mut c = Client::connect(server.local_addr(), "");
    // The scene fixes the cap y > 0.8: a tip at the top reaches only fixed vertices.
    c.send(r#"{"press": [0, 1, 0], "radius": 0.3}"#);
    let e = c.error();
    assert!(e.contains("vertices the scene fixes (vertex "), "{e}");
    assert!(!e.contains("did not settle") && !e.contains(" 0 vertices"), "{e}");
    c.send(r#"{"reset": true}"#);
    assert!(c.frame().tools.is_empty(), "the refused tip was not kept");
}

#[test]
fn overlapping_grasps_are_refused_with_both_named() {
    use fibfluid_interact::Interactive;
    let (scene, body) = sphere();
    let server = serve_with(&scene, &body, test_options());
    let mut c = Client::connect(server.local_addr(), "");
    let r = body.rest_positions();
    let dist = |a: [f64; 3], b: [f64; 3]| {
        ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
    };
    let v = (0..r.len()).min_by(|&a, &b| r[a][1].total_cmp(&r[b][1])).unwrap();
    let u = (0..r.len()).find(|&u| (0.2..0.5).contains(&dist(r[u], r[v]))).unwrap();
    let grasp = |w: usize, dy: f64| {
        format!(
            r#"{{"grasp": {w}, "radius": 0.3, "to": [{:e}, {:e}, {:e}]}}"#,
            r[w][0],
            r[w][1] + dy,
            r[w][2]
        )
    };
    c.send(&grasp(v, -0.05));
    assert_eq!(c.frame().tools.len(), 1);
    c.send(&grasp(u, -0.1));
    let e = c.error();
    assert!(e.contains(&format!("the grasps around vertices {v} and {u} both hold vertex ")), "{e}");
    let top =
        (0..r.len()).filter(|&w| !body.is_fixed(w)).max_by(|&a, &b| r[a][1].total_cmp(&r[b][1])).unwrap();
    c.send(&format!(r#"{{"release": {top}}}"#));
    let f = c.frame();
    assert_eq!(f.tools.len(), 1, "only the first grasp: {:?}", f.tools);
    assert_eq!(f.tools[0]["grasp"].as_u64(), Some(v as u64));
}
