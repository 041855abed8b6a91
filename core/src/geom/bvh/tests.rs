use crate::geom::testmesh::{grid, uv_sphere, Rng, Soup};
use super::*;

#[test]
fn a_parallel_build_lays_the_tree_out_as_a_sequential_one() {
    let (pos, faces) = uv_sphere(40, 60, |_, _| 1.0);
    let sequential = Bvh::built(&pos, &faces, usize::MAX);
    for parallel_min in [8, 100, 1000] {
        let parallel = Bvh::built(&pos, &faces, parallel_min);
        assert!(parallel.pairs == sequential.pairs, "parallel_min {parallel_min}");
        assert_eq!((&parallel.tris, &parallel.ids, &parallel.slot), (&sequential.tris, &sequential.ids, &sequential.slot));
    }
}

/// A bumpy sphere of 2000 triangles with jittered vertices, plus zero-area faces.
fn bumpy() -> Soup {
    let mut rng = Rng(7);
    let (mut pos, mut faces) =
        uv_sphere(21, 50, |th, ph| 100.0 * (1.0 + 0.15 * (3.0 * th).sin() * (5.0 * ph).cos()));
    for p in pos.iter_mut() {
        *p = add(*p, rng.point(-1.5, 1.5));
    }
    faces.truncate(1997);
    let n = pos.len() as u32;
    pos.push(scale(add(pos[3], pos[4]), 0.5));
    faces.extend([[3, 3, 3], [5, 5, 6], [3, 4, n]]);
    (pos, faces)
}

fn brute_closest((pos, faces): &Soup, q: [f64; 3]) -> (f64, u32) {
    let mut best = (f64::INFINITY, u32::MAX);
    for (i, f) in faces.iter().enumerate() {
        let d2 = closest_on_triangle(q, f.map(|v| pos[v as usize])).1;
        if d2 < best.0 {
            best = (d2, i as u32);
        }
    }
    best
}

fn brute_line((pos, faces): &Soup, p: [f64; 3], d: [f64; 3], tmax: f64) -> Option<(f64, u32)> {
    let mut best: Option<(f64, u32)> = None;
    for (i, f) in faces.iter().enumerate() {
        let Some(t) = line_triangle(p, d, f.map(|v| pos[v as usize])) else { continue };
        if t.abs() <= tmax && best.map_or(true, |b| t.abs() < b.0.abs()) {
            best = Some((t, i as u32));
        }
    }
    best
}

#[test]
fn closest_point_agrees_with_brute_force() {
    let mesh = bumpy();
    let bvh = Bvh::new(&mesh.0, &mesh.1);
    assert_eq!(bvh.len(), 2000);
    let mut rng = Rng(11);
    for _ in 0..500 {
        let q = rng.point(-150.0, 150.0);
        let got = bvh.closest_point(q).unwrap();
        let want = brute_closest(&mesh, q);
        assert_eq!((got.dist2, got.triangle), want, "query {q:?}");
        let d = sub(got.point, q);
        assert!((dot(d, d) - got.dist2).abs() < 1e-9);
        let r = want.0.sqrt();
        assert!(bvh.any_within(q, r * 1.001) && !bvh.any_within(q, r * 0.999), "{q:?}");
    }
    let f = mesh.1[1234].map(|v| mesh.0[v as usize]);
    assert_eq!(bvh.triangle(1234), Some(f));
    assert_eq!(bvh.triangle(2000), None);
}

#[test]
fn a_hint_changes_the_work_not_the_answer() {
    let mesh = bumpy();
    let bvh = Bvh::new(&mesh.0, &mesh.1);
    let mut rng = Rng(5);
    for i in 0..500u32 {
        let q = rng.point(-150.0, 150.0);
        let plain = bvh.closest_point(q).unwrap();
        // A far hint, the answer itself, a neighbour of it and one out of range.
        for hint in [(i * 7) % 2000, plain.triangle, plain.triangle ^ 1, 5000] {
            assert_eq!(bvh.closest_point_near(q, hint), Some(plain), "query {q:?} hint {hint}");
        }
    }
    assert_eq!(Bvh::new(&[], &[]).closest_point_near([0.0; 3], 0), None);
}

#[test]
fn a_refitted_hierarchy_answers_as_a_new_one() {
    let (pos, faces) = bumpy();
    let old = Bvh::new(&pos, &faces);
    let mut rng = Rng(9);
    let moved: Vec<[f64; 3]> = pos.iter().map(|&p| add(p, rng.point(-4.0, 4.0))).collect();
    let (refitted, fresh) = (old.refitted(&moved, &faces), Bvh::new(&moved, &faces));
    for _ in 0..500 {
        let q = rng.point(-150.0, 150.0);
        assert_eq!(refitted.closest_point(q), fresh.closest_point(q), "query {q:?}");
        let d = normalize_dir(rng.point(-1.0, 1.0));
        assert_eq!(refitted.intersect_line(q, d, 1e3), fresh.intersect_line(q, d, 1e3));
    }
    assert_eq!(refitted.triangle(77), fresh.triangle(77));
}

fn normalize_dir(d: [f64; 3]) -> [f64; 3] {
    scale(d, 1.0 / dot(d, d).sqrt().max(1e-9))
}

#[test]
fn line_hits_agree_with_brute_force() {
    let mesh = bumpy();
    let bvh = Bvh::new(&mesh.0, &mesh.1);
    let mut rng = Rng(13);
    let mut hits = 0;
    for i in 0..500 {
        let p = rng.point(-150.0, 150.0);
        // Every other line is aimed near a vertex, so that many lines hit.
        let vertex = mesh.0[(rng.unit() * mesh.0.len() as f64) as usize];
        let aim = add(vertex, rng.point(-2.0, 2.0));
        let d = if i % 2 == 0 { sub(aim, p) } else { rng.point(-1.0, 1.0) };
        let tmax = [10.0, 80.0, f64::INFINITY][i % 3];
        let got = bvh.intersect_line(p, d, tmax).map(|h| (h.t, h.triangle));
        assert_eq!(got, brute_line(&mesh, p, d, tmax), "line {p:?} + t {d:?}");
        hits += usize::from(got.is_some());
    }
    assert!(hits > 250, "too few hits ({hits}) to test anything");
}

#[test]
fn line_looks_both_ways_and_respects_t_max() {
    let (pos, faces) = grid(3, 3, 1.0, [0.0, 0.0, 0.0]);
    let bvh = Bvh::new(&pos, &faces);
    let hit = bvh.intersect_line([0.5, 0.5, 2.0], [0.0, 0.0, 0.5], 10.0).unwrap();
    assert!((hit.t + 4.0).abs() < 1e-12 && hit.point[2].abs() < 1e-12);
    assert!(bvh.intersect_line([0.5, 0.5, 2.0], [0.0, 0.0, 1.0], 1.9).is_none());
    assert!(bvh.intersect_line([0.5, 0.5, 2.0], [1.0, 0.0, 0.0], 1e9).is_none());
}

#[test]
fn nearest_of_two_sheets_and_ties_go_to_lowest_index() {
    let (mut pos, mut faces) = grid(2, 2, 10.0, [0.0, 0.0, 0.0]);
    let (p2, f2) = grid(2, 2, 10.0, [0.0, 0.0, 4.0]);
    pos.extend(p2);
    faces.extend(f2.iter().map(|f| f.map(|v| v + 4)));
    let bvh = Bvh::new(&pos, &faces);
    let hit = bvh.intersect_line([3.0, 1.0, 3.0], [0.0, 0.0, -1.0], 100.0).unwrap();
    assert_eq!((hit.t, hit.triangle), (-1.0, 2));
    let cp = bvh.closest_point([3.0, 1.0, 1.0]).unwrap();
    assert_eq!((cp.point, cp.triangle, cp.dist2), ([3.0, 1.0, 0.0], 0, 1.0));
    // On the shared diagonal both triangles are at distance 1: the lower index wins.
    let cp = bvh.closest_point([5.0, 5.0, -1.0]).unwrap();
    assert_eq!((cp.triangle, cp.dist2), (0, 1.0));
    let hit = bvh.intersect_line([5.0, 5.0, 2.0], [0.0, 0.0, 1.0], 100.0).unwrap();
    assert_eq!((hit.t, hit.triangle), (-2.0, 0));
}

#[test]
fn degenerate_and_empty_meshes_do_not_panic() {
    let pos = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]];
    let bvh = Bvh::new(&pos, &[[0, 1, 2], [1, 1, 1], [0, 0, 2]]);
    let cp = bvh.closest_point([1.5, 2.0, 0.0]).unwrap();
    assert_eq!((cp.point, cp.dist2), ([1.5, 0.0, 0.0], 4.0));
    assert_eq!(bvh.closest_point([-1.0, 0.0, 0.0]).unwrap().point, [0.0; 3]);
    assert!(bvh.intersect_line([1.0, 0.0, 1.0], [0.0, 0.0, 1.0], 1e9).is_none());
    let empty = Bvh::new(&pos, &[]);
    assert!(empty.is_empty());
    assert!(empty.closest_point([0.0; 3]).is_none());
    assert!(empty.intersect_line([0.0; 3], [1.0, 0.0, 0.0], 1.0).is_none());
}
