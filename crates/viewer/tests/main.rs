//! Integration tests of the viewer: the protocol over real sockets, compared with a body
//! driven directly; the frame rate at N = 10,242 (ignored: reports, never asserts); and,
//! with the `browser` feature, the page in a real headless browser.

mod common;
mod frame_rate;
mod protocol;

#[cfg(feature = "browser")]
mod browser;
