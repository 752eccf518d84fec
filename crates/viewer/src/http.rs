//! The HTTP side of a connection: reading and checking a request head within a size and
//! time limit, checking a WebSocket handshake, writing short answers and closing without
//! losing them.

use std::io::{ErrorKind, Read, Write};
use std::net::{Shutdown, TcpStream};
use std::time::{Duration, Instant};

/// Largest request head read (bytes); a longer one is answered 431.
pub(crate) const MAX_HEAD: usize = 16 * 1024;
/// Most header lines in a request head; more are answered 431.
pub(crate) const MAX_HEADERS: usize = 100;
/// How long a connection is drained after its answer so that closing it does not reset
/// the answer away (a client that is still sending when the socket closes gets a TCP
/// reset, which can discard the answer it has not read yet).
const LINGER: Duration = Duration::from_secs(1);
/// Most bytes drained after an answer.
const LINGER_BYTES: usize = 256 * 1024;

/// A parsed request head.
#[derive(Debug)]
pub(crate) struct Head {
    /// `GET`, `HEAD`, ...
    pub method: String,
    /// The request target (`/ws?method=ffm`).
    pub target: String,
    /// `HTTP/1.1` or `HTTP/1.0`.
    pub version: String,
    /// Header lines in order, names as sent.
    pub headers: Vec<(String, String)>,
    /// Bytes read past the head (a WebSocket client may send its first frame at once).
    pub rest: Vec<u8>,
}

impl Head {
    /// The values of every header named `name` (case-insensitive).
    pub fn values<'a>(&'a self, name: &'a str) -> impl Iterator<Item = &'a str> + 'a {
        self.headers.iter().filter(move |(k, _)| k.eq_ignore_ascii_case(name)).map(|(_, v)| v.as_str())
    }

    /// Whether a comma-separated header `name` lists `token` (case-insensitive).
    pub fn lists(&self, name: &str, token: &str) -> bool {
        self.values(name).flat_map(|v| v.split(',')).any(|t| t.trim().eq_ignore_ascii_case(token))
    }
}

/// Why no request head could be read: each but `Closed` is answered.
#[derive(Debug, PartialEq)]
pub(crate) enum HeadError {
    /// The connection closed or failed before a complete head: nobody to answer.
    Closed,
    /// Not complete within the head timeout: 408.
    TimedOut,
    /// Longer than [`MAX_HEAD`] or with more than [`MAX_HEADERS`] lines: 431.
    TooLarge(&'static str),
    /// Not an HTTP/1 request head: 400 (or 505 for another HTTP version).
    Malformed { status: &'static str, reason: String },
}

impl HeadError {
    /// The status line and the one-line reason of the answer (`None`: no answer).
    pub fn answer(&self) -> Option<(&'static str, String)> {
        match self {
            Self::Closed => None,
            Self::TimedOut => Some(("408 Request Timeout", "the request head did not arrive in time".into())),
            Self::TooLarge(what) => Some(("431 Request Header Fields Too Large", (*what).into())),
            Self::Malformed { status, reason } => Some((status, reason.clone())),
        }
    }
}

fn bad(reason: impl Into<String>) -> HeadError {
    HeadError::Malformed { status: "400 Bad Request", reason: reason.into() }
}

/// End of the head: the index just past its empty line (`\r\n\r\n`, or `\n\n` from
/// lenient clients).
fn head_end(buf: &[u8]) -> Option<usize> {
    (0..buf.len()).find_map(|i| {
        if buf[i] != b'\n' {
            return None;
        }
        match buf.get(i + 1..) {
            Some([b'\n', ..]) => Some(i + 2),
            Some([b'\r', b'\n', ..]) => Some(i + 3),
            _ => None,
        }
    })
}

/// Reads a request head within `timeout` (the whole head, however slowly it trickles in).
pub(crate) fn read_head(stream: &mut TcpStream, timeout: Duration) -> Result<Head, HeadError> {
    let deadline = Instant::now() + timeout;
    let mut buf: Vec<u8> = Vec::with_capacity(1024);
    let mut chunk = [0u8; 4096];
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return Err(HeadError::TimedOut);
        }
        if stream.set_read_timeout(Some(left)).is_err() {
            return Err(HeadError::Closed);
        }
        let n = match stream.read(&mut chunk) {
            Ok(0) => return Err(HeadError::Closed),
            Ok(n) => n,
            Err(e) if e.kind() == ErrorKind::Interrupted => continue,
            Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {
                return Err(HeadError::TimedOut);
            }
            Err(_) => return Err(HeadError::Closed),
        };
        // The empty line may straddle two reads.
        let from = buf.len().saturating_sub(2);
        buf.extend_from_slice(&chunk[..n]);
        if let Some(end) = head_end(&buf[from..]).map(|e| e + from) {
            if end > MAX_HEAD {
                return Err(HeadError::TooLarge("request head too long (16 KiB at most)"));
            }
            let rest = buf.split_off(end);
            return parse_head(&buf, rest);
        }
        if buf.len() > MAX_HEAD {
            return Err(HeadError::TooLarge("request head too long (16 KiB at most)"));
        }
    }
}

/// Whether `s` is an HTTP token (a method or a header name).
fn is_token(s: &str) -> bool {
    !s.is_empty() && s.bytes().all(|b| b.is_ascii_alphanumeric() || b"!#$%&'*+-.^_`|~".contains(&b))
}

/// Parses a complete head (its bytes up to and including the empty line).
fn parse_head(bytes: &[u8], rest: Vec<u8>) -> Result<Head, HeadError> {
    let text = std::str::from_utf8(bytes).map_err(|_| bad("the request head is not UTF-8 text"))?;
    let mut lines = text.split('\n').map(|l| l.strip_suffix('\r').unwrap_or(l));
    let line = lines.next().unwrap_or("");
    let parts: Vec<&str> = line.split(' ').collect();
    let [method, target, version] = parts[..] else {
        return Err(bad("malformed request line (expected `METHOD /path HTTP/1.1`)"));
    };
    if !is_token(method) {
        return Err(bad("malformed request line: the method is not a token"));
    }
    if !target.starts_with('/') || target.bytes().any(|b| b.is_ascii_control()) {
        return Err(bad("malformed request line: the target must be a path starting with `/`"));
    }
    match version {
        "HTTP/1.1" | "HTTP/1.0" => {}
        v if v.starts_with("HTTP/") => {
            return Err(HeadError::Malformed {
                status: "505 HTTP Version Not Supported",
                reason: format!("{v} is not supported (HTTP/1.1 only)"),
            });
        }
        _ => return Err(bad("malformed request line: the version must be HTTP/1.1")),
    }
    let mut headers = Vec::new();
    for (i, line) in lines.enumerate().filter(|(_, l)| !l.is_empty()) {
        if headers.len() == MAX_HEADERS {
            return Err(HeadError::TooLarge("too many header lines (100 at most)"));
        }
        let Some((name, value)) = line.split_once(':') else {
            return Err(bad(format!("malformed header line {} (no `:`)", i + 1)));
        };
        if !is_token(name) {
            return Err(bad(format!("malformed header line {}: the name is not a token", i + 1)));
        }
        headers.push((name.to_string(), value.trim().to_string()));
    }
    Ok(Head { method: method.into(), target: target.into(), version: version.into(), headers, rest })
}

/// Why a WebSocket handshake is refused: the status line, extra header lines (each ending
/// in `\r\n`) and a one-line reason.
#[derive(Debug, PartialEq)]
pub(crate) struct Refusal {
    pub status: &'static str,
    pub headers: &'static str,
    pub reason: String,
}

fn refusal(reason: impl Into<String>) -> Refusal {
    Refusal { status: "400 Bad Request", headers: "", reason: reason.into() }
}

/// Checks a WebSocket opening handshake (RFC 6455, 4.2.1) and returns the value of its
/// `Sec-WebSocket-Accept` answer.
pub(crate) fn websocket_accept(head: &Head) -> Result<String, Refusal> {
    if head.method != "GET" {
        return Err(refusal(format!("a WebSocket handshake is a GET request, not {}", head.method)));
    }
    if head.version != "HTTP/1.1" {
        return Err(refusal("a WebSocket handshake needs HTTP/1.1"));
    }
    if !head.lists("upgrade", "websocket") {
        return Err(refusal("a WebSocket handshake needs `Upgrade: websocket`"));
    }
    if !head.lists("connection", "upgrade") {
        return Err(refusal("a WebSocket handshake needs `Connection: Upgrade`"));
    }
    let versions: Vec<&str> = head.values("sec-websocket-version").collect();
    if versions != ["13"] {
        let found = if versions.is_empty() { "none".to_string() } else { versions.join(", ") };
        return Err(Refusal {
            status: "426 Upgrade Required",
            headers: "Sec-WebSocket-Version: 13\r\n",
            reason: format!("unsupported Sec-WebSocket-Version ({found}); this server speaks version 13"),
        });
    }
    let keys: Vec<&str> = head.values("sec-websocket-key").collect();
    let [key] = keys[..] else {
        return Err(refusal("a WebSocket handshake needs exactly one Sec-WebSocket-Key"));
    };
    // 16 bytes in base64: 22 characters of the alphabet and `==`.
    let base64 = |b: u8| b.is_ascii_alphanumeric() || b == b'+' || b == b'/';
    if key.len() != 24 || !key.ends_with("==") || !key.as_bytes()[..22].iter().all(|&b| base64(b)) {
        return Err(refusal("Sec-WebSocket-Key must be 16 bytes in base64"));
    }
    Ok(tungstenite::handshake::derive_accept_key(key.as_bytes()))
}

/// Shuts the writing side and drains what the client still sends (for at most
/// [`LINGER`] and [`LINGER_BYTES`]), so that the answer written before is not lost to a
/// TCP reset; then the socket closes when dropped.
pub(crate) fn linger_close(stream: &mut TcpStream) {
    let _ = stream.flush();
    let _ = stream.shutdown(Shutdown::Write);
    let _ = stream.set_nonblocking(false);
    let deadline = Instant::now() + LINGER;
    let mut drained = 0;
    let mut sink = [0u8; 4096];
    while drained < LINGER_BYTES {
        let left = deadline.saturating_duration_since(Instant::now());
        if left.is_zero() || stream.set_read_timeout(Some(left)).is_err() {
            break;
        }
        match stream.read(&mut sink) {
            Ok(0) => break,
            Ok(n) => drained += n,
            Err(e) if e.kind() == ErrorKind::Interrupted => {}
            Err(_) => break,
        }
    }
}

/// Writes an answer with `Content-Length` and `Connection: close` (`extra`: more header
/// lines, each ending in `\r\n`), then closes the connection.
pub(crate) fn respond(
    stream: &mut TcpStream,
    status: &str,
    content_type: &str,
    extra: &str,
    body: &[u8],
    head_only: bool,
) {
    let head = format!(
        "HTTP/1.1 {status}\r\nContent-Type: {content_type}\r\nContent-Length: {}\r\nCache-Control: no-store\r\n{extra}Connection: close\r\n\r\n",
        body.len()
    );
    if stream.write_all(head.as_bytes()).is_ok() && !head_only {
        let _ = stream.write_all(body);
    }
    linger_close(stream);
}

/// Answers with a plain-text one-line reason and closes.
pub(crate) fn respond_text(stream: &mut TcpStream, status: &str, extra: &str, reason: &str) {
    respond(stream, status, "text/plain; charset=utf-8", extra, format!("{reason}\n").as_bytes(), false);
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Head, HeadError> {
        parse_head(text.as_bytes(), Vec::new())
    }

    #[test]
    fn finds_the_end_of_the_head() {
        assert_eq!(head_end(b"GET / HTTP/1.1\r\n\r\nxyz"), Some(18));
        assert_eq!(head_end(b"GET / HTTP/1.1\n\nxyz"), Some(16));
        assert_eq!(head_end(b"GET / HTTP/1.1\r\nHost: a\r\n"), None);
    }

    #[test]
    fn parses_a_handshake_and_derives_the_rfc_example_key() {
        let head = parse(
            "GET /ws?method=ffm HTTP/1.1\r\nHost: x\r\nUpgrade: websocket\r\nConnection: keep-alive, Upgrade\r\n\
             Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n",
        )
        .unwrap();
        assert_eq!(head.target, "/ws?method=ffm");
        // RFC 6455, section 1.3.
        assert_eq!(websocket_accept(&head).unwrap(), "s3pPLMBiTxaQ9kYGzzhZRbK+xOo=");
    }

    #[test]
    fn refuses_malformed_heads() {
        for (text, status) in [
            ("GARBAGE\r\n\r\n", "400 Bad Request"),
            ("GET /\r\n\r\n", "400 Bad Request"),
            ("GET  / HTTP/1.1\r\n\r\n", "400 Bad Request"),
            ("GET http://x/ HTTP/1.1\r\n\r\n", "400 Bad Request"),
            ("GET / HTTP/2.0\r\n\r\n", "505 HTTP Version Not Supported"),
            ("GET / HTTP/1.1\r\nno colon\r\n\r\n", "400 Bad Request"),
            ("GET / HTTP/1.1\r\n folded: x\r\n\r\n", "400 Bad Request"),
        ] {
            match parse(text) {
                Err(HeadError::Malformed { status: s, .. }) => assert_eq!(s, status, "{text:?}"),
                other => panic!("{text:?}: {other:?}"),
            }
        }
        let many: String = (0..=MAX_HEADERS).map(|i| format!("X-{i}: y\r\n")).collect();
        assert!(matches!(parse(&format!("GET / HTTP/1.1\r\n{many}\r\n")), Err(HeadError::TooLarge(_))));
    }
}
