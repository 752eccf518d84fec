//! The dense backends refuse a system whose dense form would not fit in memory, before
//! allocating it, with an error that says how much is needed and names the structured
//! backend.

use fibfluid::linalg::{
    Blocks, BorderedMatrix, DENSE_MEMORY_FRACTION, LinalgError, Mat, available_memory_bytes,
    check_dense_memory,
};

const GIB: f64 = 1024.0 * 1024.0 * 1024.0;

/// A field of `/proc/meminfo`, in bytes.
fn meminfo_bytes(field: &str) -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with(field))?;
    Some(line.split_whitespace().nth(1)?.parse::<u64>().ok()? * 1024)
}

/// Peak resident memory of this process so far, in bytes.
fn peak_rss_bytes() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = text.lines().find(|l| l.starts_with("VmHWM:"))?;
    Some(line.split_whitespace().nth(1)?.parse::<u64>().ok()? * 1024)
}

/// Memory the limit can never exceed: the machine's total (available memory is at most
/// that), so a size above `DENSE_MEMORY_FRACTION` of it is refused whatever else runs.
fn ceiling_bytes() -> Option<f64> {
    available_memory_bytes()?;
    Some(meminfo_bytes("MemTotal:")? as f64)
}

/// The smallest system dimension whose `copies` dense f64 copies exceed `bytes`.
fn dim_needing(bytes: f64, copies: usize) -> usize {
    (bytes / (8.0 * copies as f64)).sqrt().ceil() as usize + 1
}

fn assert_too_large_message(e: &LinalgError, dim: usize) {
    let LinalgError::TooLarge { dim: d, gib, limit_gib } = e else {
        panic!("expected TooLarge, got {e:?}");
    };
    assert_eq!(*d, dim);
    let need = dim as f64 * dim as f64 * 8.0 * 2.0 / GIB;
    assert!((gib - need).abs() < 1e-9 * need, "{gib} GiB reported, {need} GiB needed");
    assert!(gib > limit_gib);
    let msg = e.to_string();
    assert!(msg.contains(&format!("needs {need:.1} GiB")), "{msg}");
    assert!(msg.contains(&format!("{limit_gib:.1} GiB allowed")), "{msg}");
    assert!(msg.contains("`structured` backend"), "{msg}");
}

#[test]
fn the_check_refuses_a_system_larger_than_the_limit_and_accepts_a_small_one() {
    let Some(ceiling) = ceiling_bytes() else {
        eprintln!("note: the available memory is unknown on this system; the memory guard test is skipped");
        return;
    };
    let dim = dim_needing(ceiling * DENSE_MEMORY_FRACTION * 1.05, 2);
    let e = check_dense_memory(dim, 2).expect_err("a system above the limit must be refused");
    assert_too_large_message(&e, dim);
    // Far below the limit (16 MiB): accepted.
    check_dense_memory(1000, 2).unwrap();
    // The limit follows the available memory: a tenth of it passes.
    let available = available_memory_bytes().unwrap() as f64;
    check_dense_memory(dim_needing(available / 10.0, 2) - 2, 2).unwrap();
}

#[cfg(feature = "faer-lu")]
#[test]
fn faer_lu_refuses_before_allocating_the_dense_matrix() {
    use fibfluid::linalg::{FaerLu, LinearSolver};
    let Some(ceiling) = ceiling_bytes() else {
        eprintln!("note: the available memory is unknown on this system; the memory guard test is skipped");
        return;
    };
    // 3N + 1 just above the limit; the shared N x N block itself is 1/18 of that (< 1 GiB
    // on a 24 GiB machine), the dense matrix and its factors the whole of it.
    let dim = dim_needing(ceiling * DENSE_MEMORY_FRACTION * 1.05, 2);
    let n = dim.div_ceil(3);
    let dim = 3 * n + 1;
    let border = vec![vec![1.0; n]; 3];
    let a = BorderedMatrix::new(Blocks::Shared(Mat::identity(n, n)), border, 1.0);
    assert_eq!(a.dim(), dim);
    let before = peak_rss_bytes();
    let e = match FaerLu.factorize(&a, &Default::default()) {
        Ok(_) => panic!("a {dim} x {dim} dense factorization must be refused"),
        Err(e) => e,
    };
    assert_too_large_message(&e, dim);
    // Refused without forming the dense matrix: the peak memory barely grew.
    if let (Some(b), Some(a)) = (before, peak_rss_bytes()) {
        let grown = a.saturating_sub(b) as f64;
        assert!(grown < 64.0 * 1024.0 * 1024.0, "peak memory grew by {:.2} GiB", grown / GIB);
    }
}
