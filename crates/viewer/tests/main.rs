//! Integration tests of the viewer: the protocol over real sockets, compared with a body
//! driven directly; the result guards of each frame; hostile clients and a lowered
//! descriptor limit; the frame rate at N = 10,242 and the time to the first touch (ignored:
//! they report, never assert); and, with the `browser` feature, the page in a real headless
//! browser.

mod abuse;
mod common;
mod frame_rate;
mod guards;
mod limits;
mod protocol;

#[cfg(feature = "browser")]
mod browser;
