//! Our closest-point BVH and QEM decimation against well-kept libraries doing the same job
//! (issue 48: keep ours only where theirs is not as fast and as good), one JSON object per line
//! (`bench/bench_libraries.py` runs it and writes the table to docs/benchmarks.md):
//!
//!     cargo run --release -p dynmesh --features compare-libraries --example library_comparison [-- MESH.obj ...]
//!
//! - `bvh`: build, then 160k closest-point queries in parallel from points around a bumpy
//!   40k-triangle sphere (the encoder's displacement fit and anchor ask this), against
//!   parry3d-f64's `TriMesh` (its QBVH) and `project_local_point`; the largest difference of
//!   the distances found says whether both answer the same.
//! - `qem`: each OBJ given (a captured frame) decimated to 6 % of its faces (the base ratio
//!   at the default QP) by `base::decimate` and by meshoptimizer's `simplify` (target error
//!   unbounded, so that it reaches the count), the result's distance to the input measured as
//!   the encoder's decision measures it (area-weighted squared distance at face centroids,
//!   both directions, the larger), as RMS in units of the input box's largest side: of the
//!   decimated mesh, and of the surface the codec then predicts from it (the base refitted
//!   by `base::refit` and subdivided with the default schemes, before any displacement).

use std::time::Instant;

use dynmesh::internals::{decimate, normalize, refit_base, scale, subdivide, Bvh, Scheme};
use dynmesh::Mesh;
use parry3d_f64::math::Point;
use parry3d_f64::query::PointQuery;
use parry3d_f64::shape::TriMesh;
use rayon::prelude::*;

/// `testmesh` names its vector helpers by `crate::geom::mesh`.
mod geom {
    pub use dynmesh::internals::mesh;
}

#[allow(dead_code)]
#[path = "../src/geom/testmesh.rs"]
mod testmesh;

fn main() {
    let meshes: Vec<String> = std::env::args().skip(1).collect();
    bvh();
    for path in &meshes {
        qem(path);
    }
}

fn seconds<T>(f: impl FnOnce() -> T) -> (T, f64) {
    let t = Instant::now();
    let r = f();
    (r, t.elapsed().as_secs_f64())
}

fn bvh() {
    let radius = |t: f64, f: f64| 500.0 + 20.0 * (5.0 * t).sin() * (7.0 * f).cos();
    let (pos, faces) = testmesh::uv_sphere(100, 201, radius);
    let mut rng = testmesh::Rng(7);
    let queries: Vec<[f64; 3]> = (0..160_000).map(|_| scale(normalize(rng.point(-1.0, 1.0)), rng.range(480.0, 520.0))).collect();
    let (ours, ours_build) = seconds(|| Bvh::new(&pos, &faces));
    let (d_ours, ours_query) = seconds(|| queries.par_iter().map(|&q| ours.closest_point(q).expect("a surface").dist2.sqrt()).collect::<Vec<f64>>());
    let points: Vec<Point<f64>> = pos.iter().map(|p| Point::new(p[0], p[1], p[2])).collect();
    let (theirs, theirs_build) = seconds(|| TriMesh::new(points, faces.clone()));
    let (d_theirs, theirs_query) = seconds(|| {
        queries
            .par_iter()
            .map(|q| {
                let p = Point::new(q[0], q[1], q[2]);
                (theirs.project_local_point(&p, false).point - p).norm()
            })
            .collect::<Vec<f64>>()
    });
    let differ = d_ours.iter().zip(&d_theirs).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
    let size = format!("{} triangles, {} queries", faces.len(), queries.len());
    line("bvh build", &size, "dynmesh Bvh", ours_build, "");
    line("bvh build", &size, "parry3d-f64 TriMesh", theirs_build, "");
    line("closest point", &size, "dynmesh Bvh", ours_query, "");
    line("closest point", &size, "parry3d-f64 TriMesh", theirs_query, &format!("distances differ by at most {differ:.2e}"));
}

fn qem(path: &str) {
    let (pos, faces) = read_obj(path);
    let target = ((faces.len() as f64) * 0.06).ceil() as usize;
    let name = std::path::Path::new(path).file_name().map_or(path.to_string(), |n| n.to_string_lossy().into_owned());
    let size = format!("{name}: {} -> {target} faces", faces.len());
    let input = Bvh::new(&pos, &faces);
    let (ours, t_ours) = seconds(|| decimate(&pos, &faces, target));
    let note = |m: &Mesh| {
        let (before, after) = (rms_distance(&m.positions, &m.faces, &pos, &faces, &input), refitted_distance(m, &pos, &faces, &input));
        format!("{} faces, RMS distance {before:.2e} of the box, {after:.2e} refitted and subdivided", m.faces.len())
    };
    line("qem decimation", &size, "dynmesh base::decimate", t_ours, &note(&ours));
    let flat: Vec<f32> = pos.iter().flat_map(|p| p.map(|c| c as f32)).collect();
    let bytes: &[u8] = unsafe { std::slice::from_raw_parts(flat.as_ptr().cast(), flat.len() * 4) };
    let adapter = meshopt::VertexDataAdapter::new(bytes, 12, 0).expect("positions");
    let indices: Vec<u32> = faces.iter().flatten().copied().collect();
    let (kept, t_theirs) = seconds(|| meshopt::simplify(&indices, &adapter, target * 3, f32::MAX, meshopt::SimplifyOptions::None, None));
    let theirs = Mesh::new(pos.clone(), kept.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect());
    line("qem decimation", &size, "meshoptimizer simplify", t_theirs, &note(&theirs));
}

/// [`rms_distance`] of the surface the codec predicts from the base `m`: refitted onto the
/// input, then subdivided with the default schemes (midpoint, midpoint, Loop).
fn refitted_distance(m: &Mesh, ip: &[[f64; 3]], inf: &[[u32; 3]], input: &Bvh) -> f64 {
    let schemes = [Scheme::Midpoint, Scheme::Midpoint, Scheme::Loop];
    let refitted = refit_base(m, &schemes, input);
    let sub = subdivide(&refitted, &m.faces, &schemes);
    rms_distance(&sub.positions, &sub.faces, ip, inf, input)
}

/// RMS of the larger direction's area-weighted squared distance between two surfaces, as a
/// share of the input box's largest side.
fn rms_distance(p: &[[f64; 3]], f: &[[u32; 3]], ip: &[[f64; 3]], inf: &[[u32; 3]], input: &Bvh) -> f64 {
    let mse = input.mean_squared_distance(p, f).max(Bvh::new(p, f).mean_squared_distance(ip, inf));
    let side = (0..3).map(|k| ip.iter().map(|q| q[k]).fold(f64::MIN, f64::max) - ip.iter().map(|q| q[k]).fold(f64::MAX, f64::min)).fold(0.0, f64::max);
    mse.sqrt() / side
}

/// Positions and triangles of an OBJ file (`v` lines, `f` lines fanned; indices 1-based).
fn read_obj(path: &str) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{path}: {e}"));
    let (mut pos, mut faces) = (Vec::new(), Vec::new());
    for l in text.lines() {
        let mut t = l.split_whitespace();
        match t.next() {
            Some("v") => pos.push([0, 1, 2].map(|_| t.next().and_then(|x| x.parse().ok()).expect("a coordinate"))),
            Some("f") => {
                let c: Vec<u32> = t.map(|x| x.split('/').next().and_then(|i| i.parse::<u32>().ok()).expect("an index") - 1).collect();
                faces.extend((1..c.len() - 1).map(|k| [c[0], c[k], c[k + 1]]));
            }
            _ => {}
        }
    }
    (pos, faces)
}

fn line(what: &str, size: &str, by: &str, seconds: f64, note: &str) {
    let row = format!(
        "{{\"measurement\": \"{what}\", \"size\": \"{size}\", \"implementation\": \"{by}\", \"ms\": {:.1}, \"note\": \"{note}\"}}",
        seconds * 1e3
    );
    println!("{row}");
}
