//! Real-time probing: frame updates of the precomputed response against full solves.
//!
//! The body is an icosphere of radius 1 (level 4: N = 2,562; level 5: N = 10,242) with the
//! paper's sphere material (Y = gamma = 3000, rho = 1000), the vertices with y > 0.8 fixed
//! (elimination), gravity (0, -10, 0) in full as the base state, paper mode. The body is
//! built outside the timing (`fibfluid::interact::build_body`: one structured solve for the
//! base state, then the precompute, whose time and memory are printed).
//!
//! Cases:
//! - `probe/frame/N/k`: a full-field frame while the tool drags k grabbed vertices (the
//!   displacement changes every frame, the grabbed set does not, so the capacitance matrix
//!   is reused); `probe/regrab/N/1`: a frame whose grabbed vertex changes every time (the
//!   capacitance matrix is rebuilt and factored).
//! - `probe/reactions/N/k`: the reaction-only query (no field), the haptic path.
//! - `probe/respond/2562`: one structured solve of the same body through
//!   `Simulation::respond` (right-hand side, checked solve with residual) and
//!   `probe/solve_unrefined/2562`: the bare triangular solves.
//! - `solve_many/2562`: two right-hand sides as two checked solves vs one `solve_many`, and
//!   the time to stream the factor's bytes (N^2 f64) from memory twice.
//!
//! Besides criterion's medians, the frame and reaction cases print nearest-rank p50 / p99 /
//! max over 2,000 consecutive frames timed one by one (`Instant`), the latency a haptic loop
//! sees.
//!
//! The response is lazy by default (the base solve's factorization kept, a vertex's
//! compliance columns computed when it is first touched: `first touch` is printed, and the
//! frames timed are those after it); `FIBFLUID_PROBE_PRECOMPUTE=full` times the full
//! precompute instead (f64 at N = 2,562, f32 at N = 10,242). After each build the process's
//! peak resident memory (`VmHWM` of /proc/self/status) is printed next to the bytes of the
//! factorization.
//!
//! Run: `cargo bench --bench probe -- --measurement-time 3 --warm-up-time 1`.

use std::hint::black_box;
use std::time::Instant;

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use fibfluid::geometry::Vec3;
use fibfluid::interact::{FfmBody, Interactive, Precompute, Storage};
use fibfluid::interact::{Latency, ProbeOptions, build_body, linearized};
use fibfluid::linalg::FactorizationExt;
use fibfluid::linalg::threads::pin_threads;
use fibfluid::{Mode, Model, Simulation};

fn scene(level: u32) -> Model {
    let mut scene = fibfluid::sim::samples::hanging_sphere(level).expect("the icosphere is a closed surface");
    scene.load.steps = 1;
    scene.solver.mode = Mode::Paper;
    scene
}

/// `k` free vertices spread over the lower half (y < 0), the first the lowest.
fn tool_vertices(body: &FfmBody, k: usize) -> Vec<usize> {
    let rest = body.rest_positions();
    let mut lower: Vec<usize> = (0..rest.len()).filter(|&v| rest[v][1] < 0.0 && !body.is_fixed(v)).collect();
    lower.sort_by(|&a, &b| rest[a][1].total_cmp(&rest[b][1]));
    let step = lower.len() / k.max(1);
    (0..k).map(|j| lower[j * step]).collect()
}

/// The target of grabbed vertex `j` in frame `t`: its base displacement plus a small
/// drag that changes every frame.
fn target(body: &FfmBody, v: usize, t: usize) -> Vec3 {
    let b = body.base_field()[v];
    let s = 0.01 * ((t % 100) as f64 / 100.0);
    [b[0] + s, b[1] - 0.5 * s, b[2]]
}

/// The precompute of this run (`FIBFLUID_PROBE_PRECOMPUTE`, default lazy).
fn precompute() -> Precompute {
    std::env::var("FIBFLUID_PROBE_PRECOMPUTE").map_or(Precompute::Lazy, |v| v.parse().expect("full or lazy"))
}

/// A line of /proc/self/status in bytes (`VmHWM`: the peak resident set), when readable.
fn status_bytes(key: &str) -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with(key))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

fn build(level: u32, storage: Storage) -> FfmBody {
    let scene = scene(level);
    let n = scene.n_vertices();
    let precompute = precompute();
    let start = Instant::now();
    let opts = ProbeOptions { storage, precompute, max_memory_bytes: None, ..Default::default() };
    let pb = build_body(&scene, &opts).expect("probe body");
    let factor = (8 * n * n) as f64;
    let hwm = status_bytes("VmHWM:").unwrap_or(0) as f64;
    println!(
        "probe N = {n} ({precompute}, {}): base solve {:.3} s, precompute {:.3} s, {:.1} MiB held, built in {:.3} s; VmHWM {:.1} MiB = {:.2} x the factor ({:.1} MiB)",
        pb.body.compliance().storage(),
        pb.base_seconds,
        pb.precompute_seconds,
        pb.body.memory_bytes() as f64 / 1048576.0,
        start.elapsed().as_secs_f64(),
        hwm / 1048576.0,
        hwm / factor,
        factor / 1048576.0
    );
    pb.body
}

/// Times `frames` consecutive frames one by one.
fn latency(body: &mut FfmBody, vertices: &[usize], frames: usize, reactions_only: bool) -> Latency {
    let mut samples = Vec::with_capacity(frames);
    for t in 0..frames {
        let start = Instant::now();
        for &v in vertices {
            let d = target(body, v, t);
            body.grab(v, d).expect("grab");
        }
        if reactions_only {
            black_box(body.update_reactions().expect("reactions"));
        } else {
            black_box(body.update().expect("frame"));
        }
        samples.push(start.elapsed().as_secs_f64() * 1e6);
    }
    Latency::of(&samples)
}

fn drag(c: &mut Criterion, group: &str, body: &mut FfmBody, n: usize, k: usize, reactions_only: bool) {
    let vertices = tool_vertices(body, k);
    body.release_all();
    // The first frame with these vertices (lazy: their columns are computed now).
    for &v in &vertices {
        let d = target(body, v, 0);
        body.grab(v, d).expect("grab");
    }
    let start = Instant::now();
    body.update().expect("first frame");
    println!(
        "probe/{group}/{n}/{k}: first frame with these vertices {:.1} ms",
        start.elapsed().as_secs_f64() * 1e3
    );
    let mut t = 0;
    c.benchmark_group(format!("probe/{group}/{n}")).bench_function(BenchmarkId::from_parameter(k), |b| {
        b.iter(|| {
            for &v in &vertices {
                let d = target(body, v, t);
                body.grab(v, d).expect("grab");
            }
            t += 1;
            if reactions_only {
                black_box(body.update_reactions().expect("reactions").len())
            } else {
                black_box(body.update().expect("frame").len())
            }
        })
    });
    let l = latency(body, &vertices, 2000, reactions_only);
    println!(
        "probe/{group}/{n}/{k}: 2000 frames timed one by one: p50 {:.1} us, p99 {:.1} us, max {:.1} us",
        l.p50, l.p99, l.max
    );
    body.release_all();
}

fn probe(c: &mut Criterion) {
    let threads = pin_threads();
    println!("{}", fibfluid::linalg::threads::thread_note(threads));

    // N = 2562: a frame against a structured solve of the same body.
    let mut body = build(4, Storage::F64);
    let n = body.n_vertices();
    drag(c, "frame", &mut body, n, 1, false);
    drag(c, "frame", &mut body, n, 10, false);
    {
        let pair = tool_vertices(&body, 2);
        let mut t = 0;
        c.benchmark_group(format!("probe/regrab/{n}")).bench_function(BenchmarkId::from_parameter(1), |b| {
            b.iter(|| {
                let v = pair[t % 2];
                body.release_all();
                let d = target(&body, v, t);
                body.grab(v, d).expect("grab");
                t += 1;
                black_box(body.update().expect("frame").len())
            })
        });
    }
    let v = tool_vertices(&body, 1)[0];
    drop(body);
    let mut sim = Simulation::new(linearized(&scene(4))).expect("simulation");
    {
        let mut g = c.benchmark_group(format!("probe/respond/{n}"));
        g.sample_size(10);
        g.bench_function(BenchmarkId::from_parameter(1), |b| {
            b.iter(|| black_box(sim.respond(&[(v, [10.0, -5.0, 0.0])]).expect("respond").1))
        });
        g.finish();
    }
    let f = sim.factorization();
    let dim = f.matrix().dim();
    let rhs: Vec<f64> = (0..dim).map(|i| ((i * 7919) % 1000) as f64 / 1000.0 - 0.5).collect();
    {
        let mut g = c.benchmark_group(format!("probe/solve_unrefined/{n}"));
        g.sample_size(10);
        g.bench_function(BenchmarkId::from_parameter(1), |b| {
            b.iter(|| {
                let mut x = rhs.clone();
                f.solve_unrefined(&mut x);
                black_box(x[0])
            })
        });
        g.finish();
    }
    {
        let two: Vec<f64> = rhs.iter().chain(rhs.iter().rev()).copied().collect();
        let mut g = c.benchmark_group(format!("solve_many/{n}"));
        g.sample_size(10);
        g.bench_function("two solves", |b| {
            b.iter(|| {
                let a = f.solve(&two[..dim]).expect("solve");
                let b2 = f.solve(&two[dim..]).expect("solve");
                black_box(a.x[0] + b2.x[0])
            })
        });
        g.bench_function("solve_many(2)", |b| {
            b.iter(|| black_box(f.solve_many(&two, 2).expect("solve_many")[1].x[0]))
        });
        // Streaming the factor's bytes twice: one N x N f64 buffer (as large as the
        // factor) summed twice.
        let buffer = vec![1.0f64; n * n];
        g.bench_function("stream factor bytes twice", |b| {
            b.iter(|| {
                // Eight independent sums so the loop vectorizes and is bound by memory,
                // not by the latency of one chain of additions.
                let mut acc = [0.0f64; 8];
                for _ in 0..2 {
                    for chunk in black_box(&buffer).chunks_exact(8) {
                        for (a, x) in acc.iter_mut().zip(chunk) {
                            *a += x;
                        }
                    }
                }
                black_box(acc.iter().sum::<f64>())
            })
        });
        g.finish();
    }
    drop(sim);

    // N = 10242: frame latency, reaction-only queries and the f32 precompute.
    let mut body = build(5, Storage::F32);
    let n = body.n_vertices();
    for k in [1, 5, 10] {
        drag(c, "frame", &mut body, n, k, false);
    }
    for k in [1, 5, 10] {
        drag(c, "reactions", &mut body, n, k, true);
    }
}

criterion_group!(benches, probe);
criterion_main!(benches);
