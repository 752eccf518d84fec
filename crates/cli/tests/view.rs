//! `fibfluid view` end to end: the binary serves the scene's mesh on the printed URL; bad
//! flags and a port in use are one-line errors with exit code 2 (the protocol itself is
//! tested in crates/viewer).

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

fn sphere() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/scenes/sphere.toml")
}

fn view(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_fibfluid")).arg("view").arg(sphere()).args(args).output().unwrap()
}

fn one_error_line(out: &std::process::Output, fragment: &str) {
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    let errors: Vec<&str> = err.lines().filter(|l| l.starts_with("error:")).collect();
    assert_eq!(errors.len(), 1, "{err}");
    assert!(errors[0].contains(fragment), "`{}` lacks `{fragment}`", errors[0]);
}

#[test]
fn view_serves_the_scene_on_the_printed_url() {
    let mut child = Command::new(env!("CARGO_BIN_EXE_fibfluid"))
        .arg("view")
        .arg(sphere())
        .args(["--port", "0"])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap()).read_line(&mut line).unwrap();
    let result = std::panic::catch_unwind(|| {
        let url =
            line.split_whitespace().find(|w| w.starts_with("http://")).expect("a URL on the first line");
        let addr = url.trim_start_matches("http://").trim_end_matches('/');
        assert!(addr.starts_with("127.0.0.1:"), "bound to 127.0.0.1 by default: {addr}");
        let mut s = TcpStream::connect(addr).unwrap();
        write!(s, "GET /mesh HTTP/1.1\r\nHost: {addr}\r\n\r\n").unwrap();
        let mut answer = Vec::new();
        s.read_to_end(&mut answer).unwrap();
        let end = answer.windows(4).position(|w| w == b"\r\n\r\n").unwrap();
        assert!(answer.starts_with(b"HTTP/1.1 200 OK"));
        let mesh: serde_json::Value = serde_json::from_slice(&answer[end + 4..]).unwrap();
        assert_eq!(mesh["positions"].as_array().unwrap().len(), 3 * 162);
        assert_eq!(mesh["triangles"].as_array().unwrap().len(), 3 * 320);
    });
    child.kill().unwrap();
    child.wait().unwrap();
    if let Err(e) = result {
        std::panic::resume_unwind(e);
    }
}

#[test]
fn view_refuses_bad_flags_and_a_port_in_use() {
    one_error_line(&view(&["--method", "bogus"]), "`bogus` is not a method");
    one_error_line(&view(&["--max-clients", "0"]), "--max-clients 0: must be at least 1");
    let taken = TcpListener::bind("127.0.0.1:0").unwrap();
    let port = taken.local_addr().unwrap().port().to_string();
    one_error_line(&view(&["--port", &port]), &format!("cannot listen on 127.0.0.1:{port}"));
    let out =
        Command::new(env!("CARGO_BIN_EXE_fibfluid")).args(["view", "no-such-scene.toml"]).output().unwrap();
    one_error_line(&out, "no-such-scene.toml");
}
