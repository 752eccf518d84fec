//! The server under a lowered limit of open files, as with the usual `ulimit -n 1024` and
//! more idle connections than descriptors. The server runs in a child process (this test
//! binary run again, through `sh -c 'ulimit -n 128 && exec ...'`, so that the limit of the
//! test process itself is untouched), and reports its counters on request; the test opens
//! the idle connections to 127.0.0.1 from this process.

use std::io::{BufRead, BufReader, Write};
use std::net::{SocketAddr, TcpStream};
use std::process::{Command, Stdio};
use std::sync::mpsc::{Receiver, channel};
use std::time::Duration;

use fibfluid_interact::Storage;
use fibfluid_viewer::{ServerOptions, ServerStats, default_max_connections};

use crate::common::{ANSWER_TIMEOUT, connect, eventually, raw_request, scene_body, serve_with};
use crate::common::{sphere_path, status_line, test_options};

/// Set in the child's environment: run the server.
const CHILD: &str = "FIBFLUID_VIEWER_LIMITS_CHILD";
/// Set in the child's environment: its `max_connections` (default: derived from its limit).
const CHILD_MAX_CONNECTIONS: &str = "FIBFLUID_VIEWER_LIMITS_MAX_CONNECTIONS";
/// The child's limit of open files.
const CHILD_FILES: usize = 128;
/// How long the child may take to build its body and report its address.
const CHILD_START: Duration = Duration::from_secs(300);

/// The server of the tests below; does nothing unless run by them.
#[test]
#[ignore = "the server of the descriptor-limit tests, which run it in a child process"]
fn descriptor_limit_child() {
    if std::env::var_os(CHILD).is_none() {
        return;
    }
    let max_connections = std::env::var(CHILD_MAX_CONNECTIONS)
        .ok()
        .map(|v| v.parse().expect("a number"))
        .unwrap_or_else(default_max_connections);
    let (scene, body) = scene_body(sphere_path(), Storage::F64);
    let opts = ServerOptions { max_connections, head_timeout: Duration::from_secs(600), ..test_options() };
    let server = serve_with(&scene, &body, opts);
    println!("child-addr {}", server.local_addr());
    std::io::stdout().flush().unwrap();
    // One line `stats` asks for the counters; the end of the input ends the child.
    for line in std::io::stdin().lines() {
        if line.unwrap().trim() == "stats" {
            let s = server.stats();
            println!("child-stats {} {} {} {}", s.connections, s.clients, s.refused, s.accept_errors);
            std::io::stdout().flush().unwrap();
        }
    }
}

/// The child server; killed when dropped.
struct Child {
    process: std::process::Child,
    lines: Receiver<String>,
    addr: SocketAddr,
}

impl Child {
    fn start(max_connections: Option<usize>) -> Self {
        let exe = std::env::current_exe().expect("the test binary");
        let mut cmd = Command::new("sh");
        cmd.arg("-c")
            .arg(format!("ulimit -n {CHILD_FILES} && exec \"$0\" \"$@\""))
            .arg(exe)
            .args(["limits::descriptor_limit_child", "--exact", "--ignored", "--nocapture"])
            .args(["--test-threads=1"])
            .env(CHILD, "1")
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::null());
        if let Some(m) = max_connections {
            cmd.env(CHILD_MAX_CONNECTIONS, m.to_string());
        }
        let mut process = cmd.spawn().expect("starts the child");
        let stdout = process.stdout.take().unwrap();
        let (send, lines) = channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                if send.send(line).is_err() {
                    return;
                }
            }
        });
        let mut child = Self { process, lines, addr: "127.0.0.1:1".parse().unwrap() };
        let addr = child.line("child-addr ", CHILD_START);
        child.addr = addr.parse().expect("an address");
        child
    }

    /// The rest of the next line of the child's output that holds `prefix`.
    fn line(&mut self, prefix: &str, timeout: Duration) -> String {
        loop {
            let line = self.lines.recv_timeout(timeout).unwrap_or_else(|e| panic!("the child: {e}"));
            // libtest may print the test's name first on the same line.
            if let Some((_, rest)) = line.split_once(prefix) {
                return rest.to_string();
            }
        }
    }

    fn stats(&mut self) -> ServerStats {
        let stdin = self.process.stdin.as_mut().unwrap();
        writeln!(stdin, "stats").and_then(|()| stdin.flush()).expect("asks the child");
        let line = self.line("child-stats ", ANSWER_TIMEOUT);
        let n: Vec<u64> = line.split(' ').map(|x| x.parse().unwrap()).collect();
        ServerStats { connections: n[0] as usize, clients: n[1] as usize, refused: n[2], accept_errors: n[3] }
    }
}

impl Drop for Child {
    fn drop(&mut self) {
        let _ = self.process.kill();
        let _ = self.process.wait();
    }
}

/// This process's soft limit of open files.
fn own_limit() -> usize {
    let text = std::fs::read_to_string("/proc/self/limits").unwrap_or_default();
    text.lines()
        .find_map(|l| l.strip_prefix("Max open files")?.split_whitespace().next()?.parse().ok())
        .unwrap_or(1024)
}

fn get_info(addr: SocketAddr) -> String {
    status_line(&raw_request(addr, b"GET /info HTTP/1.1\r\n\r\n")).to_string()
}

#[test]
fn a_normal_client_is_answered_with_more_idle_connections_than_descriptors() {
    let mut child = Child::start(None);
    let addr = child.addr;
    // 1,100 idle connections, as in the report, when this process may open them (the
    // child has 128 descriptors: any number well above that makes the point).
    let n = 1100.min(own_limit() / 2);
    assert!(n > 2 * CHILD_FILES, "this process can open only {n} connections");
    let idle: Vec<TcpStream> = (0..n).map(|_| connect(addr)).collect();
    // The cap (half the child's descriptors) holds the first 64; every other connection
    // is answered 503 at once, so the child never runs out of descriptors.
    assert!(eventually(|| child.stats().refused as usize >= n - CHILD_FILES / 2), "{:?}", child.stats());
    assert_eq!(get_info(addr), "HTTP/1.1 503 Service Unavailable");
    let stats = child.stats();
    assert_eq!(stats.connections, CHILD_FILES / 2, "{stats:?}");
    assert_eq!(stats.accept_errors, 0, "{stats:?}");

    drop(idle);
    assert!(eventually(|| get_info(addr) == "HTTP/1.1 200 OK"), "answers again after the abuse");
}

#[test]
fn accept_failures_back_off_instead_of_spinning() {
    // A cap above the child's descriptors: `accept` fails with EMFILE.
    let mut child = Child::start(Some(100_000));
    let addr = child.addr;
    let idle: Vec<TcpStream> = (0..200).map(|_| connect(addr)).collect();
    assert!(eventually(|| child.stats().accept_errors > 0), "{:?}", child.stats());
    let before = child.stats().accept_errors;
    std::thread::sleep(Duration::from_secs(1));
    let after = child.stats().accept_errors;
    // Pauses of up to 0.5 s make a few failures a second; a loop retrying at once makes
    // thousands even on a busy machine.
    assert!(after - before <= 20, "{} failed accepts in about a second: spinning", after - before);

    drop(idle);
    assert!(eventually(|| get_info(addr) == "HTTP/1.1 200 OK"), "answers again after the abuse");
}
