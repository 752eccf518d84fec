//! ChainMail frame cost against lattice size, with and without the time-saving scheme.
//!
//! A frame is one propagation: the element at the centre of the top face of an n^3 box
//! (spacing 1, bottom layer fixed, isotropic TSVE alpha 0.05) is pushed from rest by
//! `0.025 (n - 1) (0.4, -0.2, -1)`: half of what the column under it can absorb
//! (`0.05 (n - 1)`), so the push stays compatible with the fixed layer and the moved
//! region grows with the lattice (44 of 512 elements at n = 8, 2,736 of 32,768 at n = 32). The lattice is put back at rest
//! outside the timing (`iter_batched`).
//! With TSVE relaxation the frame adds `relaxation` sweeps of the tetrahedra; that part is
//! the same with and without TSS and is timed separately (`relax_10_sweeps`).
//!
//! Run: `cargo bench -p fibfluid-chainmail --bench frame`.

use criterion::{BatchSize, BenchmarkId, Criterion, criterion_group, criterion_main};
use fibfluid_chainmail::{Lattice, PropagationOptions, RelaxOptions, Scheme, TsveMaterial};

fn lattice(n: usize) -> (Lattice, TsveMaterial, usize, [f64; 3]) {
    let mut l = Lattice::new_box([n; 3], 1.0, [0.0; 3]).expect("box");
    for i in 0..n {
        for j in 0..n {
            let e = l.element_at([i, j, 0]).expect("bottom");
            l.set_inverse_mass(e, 0.0).expect("fix");
        }
    }
    let m = TsveMaterial::isotropic(l.len(), 0.05);
    let top = l.element_at([n / 2, n / 2, n - 1]).expect("top");
    let p = l.positions()[top];
    let s = 0.025 * (n - 1) as f64;
    (l, m, top, [p[0] + 0.4 * s, p[1] - 0.2 * s, p[2] - s])
}

fn frame(c: &mut Criterion) {
    let mut g = c.benchmark_group("chainmail_frame");
    g.sample_size(20);
    for n in [8usize, 16, 24, 32] {
        let (l, m, top, target) = lattice(n);
        // The work of one frame per scheme (not timed), for the table in docs/performance.md.
        for scheme in [Scheme::TimeSaving, Scheme::Exhaustive] {
            let r = l
                .clone()
                .propagate(
                    &m,
                    &[(top, target)],
                    &PropagationOptions { scheme, ..PropagationOptions::default() },
                )
                .expect("propagate");
            println!(
                "n^3 = {}: {scheme:?}: moved {}, processed {}, CBR checks {}",
                l.len(),
                r.moved,
                r.processed,
                r.checks
            );
        }
        for (name, scheme) in [("tss", Scheme::TimeSaving), ("exhaustive", Scheme::Exhaustive)] {
            let opts = PropagationOptions { scheme, ..PropagationOptions::default() };
            g.bench_with_input(BenchmarkId::new(name, n * n * n), &n, |b, _| {
                b.iter_batched(
                    || l.clone(),
                    |mut l| {
                        let r = l.propagate(&m, &[(top, target)], &opts).expect("propagate");
                        assert!(r.converged && r.blocked == 0);
                        r.moved
                    },
                    BatchSize::LargeInput,
                )
            });
        }
        let relax = RelaxOptions { max_iterations: 10, tolerance: 0.0, ..RelaxOptions::default() };
        let mut pushed = l.clone();
        pushed.propagate(&m, &[(top, target)], &PropagationOptions::default()).expect("push");
        g.bench_with_input(BenchmarkId::new("relax_10_sweeps", n * n * n), &n, |b, _| {
            b.iter_batched(
                || pushed.clone(),
                |mut l| l.relax(&m, &[top], &relax).expect("relax").iterations,
                BatchSize::LargeInput,
            )
        });
    }
    g.finish();
}

criterion_group!(benches, frame);
criterion_main!(benches);
