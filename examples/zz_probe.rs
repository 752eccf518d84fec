//! Temporary probe.
use faer::MatMut;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::lu::partial_pivoting::factor::{lu_in_place, lu_in_place_scratch};
use fibfluid::assembly::ConstraintMethod;
use fibfluid::linalg::{FactorOptions, backend_by_name};
use std::time::Instant;

fn lu(mut a: MatMut<'_, f64>) {
    let dim = a.nrows();
    let par = faer::get_global_parallelism();
    let mut p = vec![0usize; dim];
    let mut q = vec![0usize; dim];
    let mut mem = MemBuffer::new(lu_in_place_scratch::<usize, f64>(dim, dim, par, Default::default()));
    lu_in_place(a.rb_mut(), &mut p, &mut q, par, MemStack::new(&mut mem), Default::default());
}
use faer::reborrow::ReborrowMut;

fn main() {
    fibfluid::bench::pin_threads();
    let n: usize = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(1000);
    let sys = fibfluid::bench::synthetic_system(n, ConstraintMethod::Eliminate).unwrap();
    let m = &sys.matrix;
    let dim = m.dim();
    let faer_b = backend_by_name("faer-lu").unwrap();
    let mut best = [f64::INFINITY; 7];
    for _ in 0..7 {
        let t = Instant::now();
        let d = m.to_dense();
        best[0] = best[0].min(t.elapsed().as_secs_f64());
        drop(d);
        let t = Instant::now();
        let d = m.to_dense_col_major();
        best[1] = best[1].min(t.elapsed().as_secs_f64());
        drop(d);
        // kernel on fresh to_dense (timed kernel only)
        let mut d = m.to_dense();
        let t = Instant::now();
        lu(d.as_mut());
        best[2] = best[2].min(t.elapsed().as_secs_f64());
        drop(d);
        // kernel on a touched copy
        let d0 = m.to_dense();
        let mut d = d0.clone();
        drop(d0);
        let t = Instant::now();
        lu(d.as_mut());
        best[3] = best[3].min(t.elapsed().as_secs_f64());
        drop(d);
        // kernel on a Vec col-major
        let mut v = m.to_dense_col_major();
        let t = Instant::now();
        lu(MatMut::from_column_major_slice_mut(&mut v, dim, dim));
        best[4] = best[4].min(t.elapsed().as_secs_f64());
        drop(v);
        let t = Instant::now();
        let f = faer_b.factorize(m, &FactorOptions::default()).unwrap();
        best[5] = best[5].min(t.elapsed().as_secs_f64());
        drop(f);
        let t = Instant::now();
        m.check_finite().unwrap();
        best[6] = best[6].min(t.elapsed().as_secs_f64());
    }
    println!(
        "n={dim} to_dense {:.4} to_dense_col_major {:.4} | kernel fresh {:.4} touched {:.4} vec {:.4} | backend {:.4} check_finite {:.4}",
        best[0], best[1], best[2], best[3], best[4], best[5], best[6]
    );
}
