//! Timings of the geometry kernels and the snapshot renderer on synthetic meshes of the codec's
//! sizes, one JSON object per line on stdout (`bench/bench_kernels.py` runs it and writes the
//! table to docs/benchmarks.md):
//!
//!     cargo run --release -p dynmesh --features internals --example kernel_timings [-- bvh fit render]
//!
//! - `bvh`: a bumpy 40k-triangle sphere: `Bvh::new` (mean of 10 builds), then 160k
//!   closest-point and 160k line queries (along the radius, t in [-30, 30]) from points at radius
//!   480 to 520, in parallel.
//! - `fit`: the same kind of target, a 5k-triangle base on it subdivided flat three times
//!   (164k vertices): the target's `Bvh::new`, `local_frames`, `fit_displacements` (normal
//!   only), and the vertices' distance to the target before and after the fit.
//! - `render`: a textured wavy sheet of about a million faces at 1024 x 1024 (mean of 5
//!   frames after one untimed).
//!
//! Each line has wall and CPU milliseconds: CPU is the on-CPU time of all the process's
//! threads (from /proc; 0 where unavailable), which says what the code costs when other work
//! on a shared machine inflates the wall time.

use dynmesh::eval::render::{render, View};
use dynmesh::internals::{fit_displacements, local_frames, normalize, scale, Bvh};
use dynmesh::texturing::{Texture, UvMesh};
use dynmesh::Mesh;
use rayon::prelude::*;

/// `testmesh` names its vector helpers by `crate::geom::mesh`.
mod geom {
    pub use dynmesh::internals::mesh;
}

/// The library's test meshes (sphere, icosphere, flat subdivision, seeded random numbers),
/// shared with its unit tests rather than copied.
#[allow(dead_code)]
#[path = "../src/geom/testmesh.rs"]
mod testmesh;

use testmesh::{icosphere, midpoint, uv_sphere, Rng};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let all = ["bvh", "fit", "render"];
    let chosen: Vec<&str> = if args.is_empty() { all.to_vec() } else { args.iter().map(String::as_str).collect() };
    for name in chosen {
        match name {
            "bvh" => bvh(),
            "fit" => fit(),
            "render" => render_million(),
            _ => {
                eprintln!("unknown measurement {name:?}: choose from {all:?}");
                std::process::exit(2);
            }
        }
    }
}

/// The radius of the target surfaces of `bvh` and `fit` (UV spheres of 40,000 triangles):
/// 500, with bumps of height `bump` and ripples of height `ripple`.
fn bumpy_radius(bump: f64, ripple: f64) -> impl Fn(f64, f64) -> f64 {
    move |th: f64, ph: f64| {
        500.0 + bump * (4.0 * th).sin() * (6.0 * ph).cos() + ripple * (17.0 * th).cos() * (13.0 * ph).sin()
    }
}

fn bvh() {
    let (pos, faces) = uv_sphere(101, 200, bumpy_radius(20.0, 0.0));
    let size = format!("{} triangles", thousands(faces.len()));
    let runs = 10;
    let (_, wall, cpu) = timed(|| (0..runs).map(|_| Bvh::new(&pos, &faces).len()).sum::<usize>());
    line("bvh build", &size, runs, wall, cpu, "");
    let bvh = Bvh::new(&pos, &faces);
    let mut rng = Rng(3);
    let qs: Vec<[f64; 3]> =
        (0..160_000).map(|_| scale(normalize(rng.point(-1.0, 1.0)), rng.range(480.0, 520.0))).collect();
    let (_, wall, cpu) = timed(|| qs.par_iter().map(|&q| bvh.closest_point(q).unwrap().dist2).sum::<f64>());
    line("bvh closest point", &format!("{} queries, {size}", thousands(qs.len())), 1, wall, cpu, "");
    let (hits, wall, cpu) =
        timed(|| qs.par_iter().filter(|&&q| bvh.intersect_line(q, normalize(q), 30.0).is_some()).count());
    let note = format!("{} hits with t in [-30, 30]", thousands(hits));
    line("bvh line", &format!("{} queries, {size}", thousands(qs.len())), 1, wall, cpu, &note);
}

fn fit() {
    let r = bumpy_radius(25.0, 4.0);
    let (tp, tf) = uv_sphere(101, 200, &r);
    let (target, wall, cpu) = timed(|| Bvh::new(&tp, &tf));
    line("bvh build", &format!("{} triangles", thousands(tf.len())), 1, wall, cpu, "the fit's target");
    let (mut base, base_faces) = icosphere(4, 1.0);
    for v in base.iter_mut() {
        *v = scale(*v, r(v[2].clamp(-1.0, 1.0).acos(), v[1].atan2(v[0])));
    }
    let note = format!("base of {} triangles subdivided flat 3 times", thousands(base_faces.len()));
    let (pos, faces) = midpoint(&(base, base_faces), 3);
    let size = format!("{} vertices", thousands(pos.len()));
    let (frames, wall, cpu) = timed(|| local_frames(&pos, &faces));
    line("local frames", &size, 1, wall, cpu, &note);
    let (d, wall, cpu) = timed(|| fit_displacements(&pos, &faces, &frames, &target, true));
    let moved: Vec<[f64; 3]> = pos.iter().zip(&d).map(|(p, d)| [p[0] + d[0], p[1] + d[1], p[2] + d[2]]).collect();
    let ((bmax, bmean), (amax, amean)) = (distance(&pos, &target), distance(&moved, &target));
    let accuracy = format!(
        "distance to the target before: max {bmax:.3}, mean {bmean:.3}; after: max {amax:.3}, mean {amean:.2e}"
    );
    line("fit displacements", &format!("{size} onto {} triangles", thousands(tf.len())), 1, wall, cpu, &accuracy);
}

/// Distances of `points` to the surface: (max, mean).
fn distance(points: &[[f64; 3]], target: &Bvh) -> (f64, f64) {
    let d: Vec<f64> = points.par_iter().map(|&p| target.closest_point(p).unwrap().dist2.sqrt()).collect();
    (d.iter().copied().fold(0.0, f64::max), d.iter().sum::<f64>() / d.len() as f64)
}

fn render_million() {
    let m = wavy_sheet(708);
    let t = checker(2048);
    let view = View { azimuth_deg: 30.0, elevation_deg: 20.0 };
    let _ = render(&m, Some(&t), 1024, 1024, view);
    let runs = 5;
    let (_, wall, cpu) = timed(|| {
        for _ in 0..runs {
            std::hint::black_box(render(&m, Some(&t), 1024, 1024, view));
        }
    });
    let size = format!("{} faces, 1024 x 1024", thousands(m.mesh.faces.len()));
    line("render", &size, runs, wall, cpu, "textured (2048 x 2048 checker)");
}

/// The test meshes' wavy sheet as a textured mesh.
fn wavy_sheet(n: u32) -> UvMesh {
    let ((p, f), uv) = testmesh::wavy_sheet(n);
    UvMesh { mesh: Mesh::new(p, f.clone()), uv, uv_faces: f }
}

/// Red and blue squares of 8 texels.
fn checker(size: usize) -> Texture {
    let rgb = (0..size * size)
        .map(|k| if (k % size / 8 + k / size / 8) % 2 == 0 { [230, 60, 40] } else { [40, 90, 220] })
        .collect();
    Texture { width: size, height: size, rgb }
}

/// `n` with commas between groups of three digits.
fn thousands(n: usize) -> String {
    let digits = n.to_string();
    let mut out = String::new();
    for (i, c) in digits.chars().enumerate() {
        if i > 0 && (digits.len() - i) % 3 == 0 {
            out.push(',');
        }
        out.push(c);
    }
    out
}

/// One measurement as a JSON object: wall and CPU milliseconds per run.
fn line(kernel: &str, size: &str, runs: usize, wall: f64, cpu: f64, note: &str) {
    let per_run = |s: f64| s * 1e3 / runs as f64;
    println!(
        "{{\"kernel\": \"{kernel}\", \"size\": \"{size}\", \"runs\": {runs}, \"wall_ms\": {:.2}, \"cpu_ms\": {:.2}, \
         \"threads\": {}, \"note\": \"{note}\"}}",
        per_run(wall),
        per_run(cpu),
        rayon::current_num_threads()
    );
}

/// Runs `f`, returning its result, wall seconds and the on-CPU seconds of all the process's
/// threads.
fn timed<T>(f: impl FnOnce() -> T) -> (T, f64, f64) {
    let (c0, t0) = (cpu_ns(), std::time::Instant::now());
    let r = f();
    (r, t0.elapsed().as_secs_f64(), cpu_ns().saturating_sub(c0) as f64 * 1e-9)
}

/// Sum of the threads' run times in /proc/self/task/*/schedstat (ns); 0 where unavailable.
/// The threads here (main and rayon's pool) live as long as the process.
fn cpu_ns() -> u64 {
    let Ok(dir) = std::fs::read_dir("/proc/self/task") else { return 0 };
    dir.flatten()
        .filter_map(|e| std::fs::read_to_string(e.path().join("schedstat")).ok())
        .filter_map(|s| s.split_whitespace().next()?.parse::<u64>().ok())
        .sum()
}
