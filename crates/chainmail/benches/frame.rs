//! ChainMail frame cost against lattice size, with and without the time-saving scheme.
//!
//! A frame is one propagation: the element at the centre of the top face of an n^3 box
//! (spacing 1, bottom layer fixed, isotropic TSVE alpha 0.05) is pushed by (0.5, -0.25, -1.5)
//! from rest, then the lattice is put back at rest (outside the timing, by `iter_batched`).
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
    (l, m, top, [p[0] + 0.5, p[1] - 0.25, p[2] - 1.5])
}

fn frame(c: &mut Criterion) {
    let mut g = c.benchmark_group("chainmail_frame");
    g.sample_size(20);
    for n in [8usize, 16, 24, 32] {
        let (l, m, top, target) = lattice(n);
        for (name, scheme) in [("tss", Scheme::TimeSaving), ("exhaustive", Scheme::Exhaustive)] {
            let opts = PropagationOptions { scheme, ..PropagationOptions::default() };
            g.bench_with_input(BenchmarkId::new(name, n * n * n), &n, |b, _| {
                b.iter_batched(
                    || l.clone(),
                    |mut l| l.propagate(&m, &[(top, target)], &opts).expect("propagate").moved,
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
