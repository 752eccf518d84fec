//! The one printing path of the command line. `say!` writes a line to stdout, `tell!` to
//! stderr. A closed stdout (`fibfluid plan SCENE | head -1`) is a normal end: the process
//! exits with code 0 without a word (as `head`'s reader expects), never with a panic; a
//! closed stderr is ignored (there is nowhere left to report to).

use std::io::Write;

/// Writes one line to stdout; a broken pipe ends the process quietly (exit 0), another
/// write error ends it with code 2 after a note on stderr.
pub fn line_out(args: std::fmt::Arguments<'_>) {
    let mut out = std::io::stdout().lock();
    if let Err(e) = out.write_fmt(args).and_then(|()| out.write_all(b"\n")).and_then(|()| out.flush()) {
        if e.kind() == std::io::ErrorKind::BrokenPipe {
            std::process::exit(0);
        }
        line_err(format_args!("error: writing to stdout: {e}"));
        std::process::exit(2);
    }
}

/// Writes one line to stderr; a failure is ignored.
pub fn line_err(args: std::fmt::Arguments<'_>) {
    let mut err = std::io::stderr().lock();
    let _ = err.write_fmt(args).and_then(|()| err.write_all(b"\n"));
}

/// `println!` through [`line_out`].
macro_rules! say {
    ($($arg:tt)*) => { $crate::say::line_out(format_args!($($arg)*)) };
}

/// `eprintln!` through [`line_err`].
macro_rules! tell {
    ($($arg:tt)*) => { $crate::say::line_err(format_args!($($arg)*)) };
}

/// `x` with six significant digits: plain between 1e-3 and 1e6, scientific outside, so a
/// micrometre body's displacement never prints as 0.000000.
pub fn num(x: f64) -> String {
    let a = x.abs();
    if x == 0.0 || !x.is_finite() {
        format!("{x}")
    } else if (1e-3..1e6).contains(&a) {
        let decimals = (5 - a.log10().floor() as i32).max(0) as usize;
        format!("{x:.decimals$}")
    } else {
        format!("{x:.5e}")
    }
}
