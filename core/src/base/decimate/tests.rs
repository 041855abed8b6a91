use super::checks::triangle_normal;
use super::*;
use crate::geom::mesh::{dist2, dot, norm};
use std::collections::BTreeMap;

/// Panics unless `m` is compact, in range, and free of degenerate and duplicate faces.
fn assert_valid(m: &Mesh) {
    let n = m.positions.len();
    let mut used = vec![false; n];
    let mut seen = std::collections::BTreeSet::new();
    for f in &m.faces {
        assert!(f.iter().all(|&v| (v as usize) < n), "index out of range in {f:?}");
        assert!(f[0] != f[1] && f[1] != f[2] && f[0] != f[2], "degenerate face {f:?}");
        assert!(seen.insert(sorted(*f)), "duplicate face {f:?}");
        f.iter().for_each(|&v| used[v as usize] = true);
    }
    assert!(used.iter().all(|&u| u), "unreferenced vertex");
    assert!(m.positions.iter().flatten().all(|c| c.is_finite()));
}

fn normal(m: &Mesh, f: [u32; 3]) -> [f64; 3] {
    triangle_normal(f.map(|v| m.positions[v as usize]))
}

/// Number of faces on each edge, keyed by sorted index pairs.
fn edge_face_counts(m: &Mesh) -> BTreeMap<(u32, u32), usize> {
    let mut count = BTreeMap::new();
    for f in &m.faces {
        for k in 0..3 {
            let (u, v) = (f[k], f[(k + 1) % 3]);
            *count.entry((u.min(v), u.max(v))).or_insert(0) += 1;
        }
    }
    count
}

/// Edges with one face, as sorted index pairs.
fn boundary_edges(m: &Mesh) -> Vec<(u32, u32)> {
    edge_face_counts(m).into_iter().filter(|&(_, c)| c == 1).map(|(e, _)| e).collect()
}

fn components(m: &Mesh) -> usize {
    let mut parent: Vec<usize> = (0..m.positions.len()).collect();
    fn find(p: &mut [usize], mut x: usize) -> usize {
        while p[x] != x {
            p[x] = p[p[x]];
            x = p[x];
        }
        x
    }
    for f in &m.faces {
        let r = find(&mut parent, f[0] as usize);
        for &v in &f[1..] {
            let s = find(&mut parent, v as usize);
            parent[s] = r;
        }
    }
    (0..parent.len()).filter(|&v| find(&mut parent, v) == v).count()
}

/// `n` x `n` squares over the unit square in z = 0, two CCW triangles each (normal +z).
fn grid(n: u32) -> Mesh {
    let mut positions = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            positions.push([i as f64 / n as f64, j as f64 / n as f64, 0.0]);
        }
    }
    let id = |i: u32, j: u32| j * (n + 1) + i;
    let mut faces = Vec::new();
    for j in 0..n {
        for i in 0..n {
            faces.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            faces.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    Mesh::new(positions, faces)
}

/// Unit icosphere with `levels` midpoint subdivisions, outward CCW faces.
fn icosphere(levels: u32) -> Mesh {
    let (positions, faces) = crate::geom::testmesh::icosphere(levels, 1.0);
    Mesh::new(positions, faces)
}

/// Cube [-1, 1]^3 with each side split into `n` x `n` squares, outward CCW faces.
fn cube(n: u32) -> Mesh {
    let mut index = BTreeMap::new();
    let mut positions = Vec::new();
    let mut faces = Vec::new();
    let mut vid = |p: [i64; 3], positions: &mut Vec<[f64; 3]>| {
        *index.entry(p).or_insert_with(|| {
            positions.push(p.map(|c| 2.0 * c as f64 / n as f64 - 1.0));
            positions.len() as u32 - 1
        })
    };
    let n = n as i64;
    for axis in 0..3 {
        for side in [0, n] {
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            let at = |i: i64, j: i64| {
                let mut p = [0; 3];
                p[axis] = side;
                p[u] = i;
                p[v] = j;
                p
            };
            for j in 0..n {
                for i in 0..n {
                    let q = [at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)]
                        .map(|p| vid(p, &mut positions));
                    // (u, v, axis) is right-handed, so CCW in (u, v) faces +axis.
                    let (t1, t2) = ([q[0], q[1], q[2]], [q[0], q[2], q[3]]);
                    if side == n {
                        faces.extend([t1, t2]);
                    } else {
                        faces.extend([[t1[0], t1[2], t1[1]], [t2[0], t2[2], t2[1]]]);
                    }
                }
            }
        }
    }
    Mesh::new(positions, faces)
}

/// Open unit-radius cylinder of height `h`, `m` segments around, `rows` rows, outward faces.
fn cylinder(m: u32, rows: u32, h: f64) -> Mesh {
    let mut positions = Vec::new();
    for r in 0..=rows {
        for k in 0..m {
            let a = 2.0 * std::f64::consts::PI * k as f64 / m as f64;
            positions.push([a.cos(), a.sin(), h * r as f64 / rows as f64]);
        }
    }
    let id = |k: u32, r: u32| r * m + k % m;
    let mut faces = Vec::new();
    for r in 0..rows {
        for k in 0..m {
            faces.push([id(k, r), id(k + 1, r), id(k + 1, r + 1)]);
            faces.push([id(k, r), id(k + 1, r + 1), id(k, r + 1)]);
        }
    }
    Mesh::new(positions, faces)
}

/// Deterministic pseudo-random radial noise on every vertex.
fn jitter(mut m: Mesh, amount: f64) -> Mesh {
    let mut s: u64 = 0x9E37_79B9_7F4A_7C15;
    for p in &mut m.positions {
        s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        let r = 1.0 + amount * (((s >> 11) as f64 / (1u64 << 53) as f64) - 0.5);
        *p = scale(*p, r);
    }
    m
}

fn run(m: &Mesh, target: usize) -> Mesh {
    let out = decimate(&m.positions, &m.faces, target);
    assert_valid(&out);
    out
}

#[test]
fn flat_grid_stays_flat_inside_its_boundary_and_reaches_the_target() {
    let input = grid(16);
    let out = run(&input, 64);
    assert!(out.faces.len() <= 64, "{} faces", out.faces.len());
    assert!(out.faces.len() >= 32, "{} faces", out.faces.len());
    for p in &out.positions {
        assert!(p[2].abs() < 1e-12, "left the plane: {p:?}");
        assert!(p[0] >= -1e-12 && p[0] <= 1.0 + 1e-12 && p[1] >= -1e-12 && p[1] <= 1.0 + 1e-12);
    }
    for corner in [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]] {
        assert!(
            out.positions.iter().any(|&p| dist2(p, corner) < 1e-24),
            "corner {corner:?} lost"
        );
    }
    // All normals up and the areas add up to the square: nothing folded, nothing torn.
    let mut area = 0.0;
    for &f in &out.faces {
        let n = normal(&out, f);
        assert!(n[2] > 0.0, "face {f:?} turned over");
        area += 0.5 * n[2];
    }
    assert!((area - 1.0).abs() < 1e-9, "area {area}");
    // The rim is still the square's perimeter.
    let mut rim = 0.0;
    for (u, v) in boundary_edges(&out) {
        let (p, q) = (out.positions[u as usize], out.positions[v as usize]);
        let on_side =
            |p: [f64; 3]| p[..2].iter().any(|&c| c.abs() < 1e-12 || (c - 1.0).abs() < 1e-12);
        assert!(on_side(p) && on_side(q), "rim vertex moved inside: {p:?} {q:?}");
        rim += dist2(p, q).sqrt();
    }
    assert!((rim - 4.0).abs() < 1e-9, "perimeter {rim}");
}

#[test]
fn sphere_stays_round_closed_and_outward() {
    let input = icosphere(3);
    let out = run(&input, 160);
    assert!(out.faces.len() <= 160 && out.faces.len() >= 150, "{} faces", out.faces.len());
    for p in &out.positions {
        let r = norm(*p);
        assert!((0.95..=1.03).contains(&r), "radius {r}");
    }
    for &f in &out.faces {
        let n = normal(&out, f);
        let c = f.iter().fold([0.0; 3], |s, &v| add(s, out.positions[v as usize]));
        assert!(dot(n, c) > 0.0, "face {f:?} points inward");
    }
    assert!(boundary_edges(&out).is_empty(), "sphere was torn open");
    let edges = out.faces.len() * 3 / 2;
    assert_eq!(
        out.positions.len() + out.faces.len() - edges,
        2,
        "Euler characteristic changed"
    );
}

#[test]
fn cube_keeps_its_corners_and_sides() {
    let input = cube(4);
    let out = run(&input, 24);
    assert!(out.faces.len() <= 24, "{} faces", out.faces.len());
    for p in &out.positions {
        let m = p.iter().fold(0.0f64, |m, c| m.max(c.abs()));
        assert!((m - 1.0).abs() < 1e-9, "vertex off the surface: {p:?}");
    }
    for corner in 0..8 {
        let c = [0, 1, 2].map(|k| if corner >> k & 1 == 1 { 1.0 } else { -1.0 });
        assert!(out.positions.iter().any(|p| dist2(*p, c) < 1e-18), "corner {c:?} lost");
    }
    for &f in &out.faces {
        let c = f.iter().fold([0.0; 3], |s, &v| add(s, out.positions[v as usize]));
        assert!(dot(normal(&out, f), c) > 0.0, "face {f:?} points inward");
    }
}

#[test]
fn open_cylinder_keeps_its_rims() {
    let input = cylinder(32, 8, 2.0);
    let out = run(&input, 64);
    assert!(out.faces.len() <= 64, "{} faces", out.faces.len());
    let rims = boundary_edges(&out);
    assert!(rims.len() >= 6, "rims collapsed to {} edges", rims.len());
    for (u, v) in rims {
        for p in [out.positions[u as usize], out.positions[v as usize]] {
            assert!(
                p[2].abs() < 1e-9 || (p[2] - 2.0).abs() < 1e-9,
                "rim left its plane: {p:?}"
            );
        }
    }
    for p in &out.positions {
        let r = (p[0] * p[0] + p[1] * p[1]).sqrt();
        assert!((0.85..=1.05).contains(&r), "radius {r}");
    }
}

#[test]
fn disjoint_components_all_survive() {
    let a = icosphere(2);
    let b = grid(6);
    let mut positions = a.positions.clone();
    let mut faces = a.faces.clone();
    let shift = |p: [f64; 3], d: f64| [p[0] + d, p[1], p[2]];
    let base = positions.len() as u32;
    positions.extend(b.positions.iter().map(|&p| shift(p, 5.0)));
    faces.extend(b.faces.iter().map(|f| f.map(|v| v + base)));
    let base = positions.len() as u32;
    positions.extend([[10.0, 0.0, 0.0], [11.0, 0.0, 0.0], [10.0, 1.0, 0.0]]);
    faces.push([base, base + 1, base + 2]);
    let input = Mesh::new(positions, faces);
    assert_eq!(components(&input), 3);
    let out = run(&input, 100);
    assert_eq!(components(&out), 3);
    assert!(out.faces.len() <= 100, "{} faces", out.faces.len());
    // Even an unreachable target leaves every component a face.
    let out = run(&input, 0);
    assert_eq!(components(&out), 3);
}

#[test]
fn output_is_identical_across_runs() {
    let input = jitter(icosphere(4), 0.02);
    let first = run(&input, 500);
    for _ in 0..3 {
        assert_eq!(run(&input, 500), first);
    }
}

#[test]
fn messy_input_does_not_panic_and_gives_a_valid_mesh() {
    let mut m = grid(8);
    let n = m.positions.len() as u32;
    m.faces.push([0, 0, 1]); // repeated index
    m.faces.push(m.faces[3]); // duplicate
    let f = m.faces[5];
    m.faces.push([f[1], f[0], f[2]]); // duplicate with the opposite orientation
    m.faces.push([0, 1, n + 7]); // out of range
    m.positions.push([0.5, 0.5, 1.0]); // fin on an interior edge: non-manifold
    let e = m.faces[40];
    m.faces.push([e[1], e[0], n]);
    m.positions.push(m.positions[10]); // duplicate vertex, own triangle
    m.faces.push([n + 1, 11, 20]);
    m.positions.push([0.25, 0.0, 0.0]); // zero-area face on the rim
    m.faces.push([0, n + 2, 2]);
    m.positions.push([f64::NAN, f64::INFINITY, 0.0]); // unusable vertex
    m.faces.push([0, 1, n + 3]);
    m.positions.push([9.0, 9.0, 9.0]); // unreferenced
    for target in [0, 1, 10, 40, 1000] {
        let out = run(&m, target);
        assert!(!out.faces.is_empty());
    }
    assert_eq!(decimate(&[], &[], 10), Mesh::default());
    assert_eq!(decimate(&[[0.0; 3]; 3], &[[0, 1, 2]], 0).faces.len(), 1);
}

#[test]
fn tiny_closed_meshes_stay_closed_and_valid() {
    let tetra = Mesh::new(
        vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
    );
    let out = run(&tetra, 0);
    assert_eq!(out, tetra, "a tetrahedron has no legal collapse");
    let octa = Mesh::new(
        vec![
            [1.0, 0.0, 0.0],
            [-1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, -1.0, 0.0],
            [0.0, 0.0, 1.0],
            [0.0, 0.0, -1.0],
        ],
        vec![
            [0, 2, 4],
            [2, 1, 4],
            [1, 3, 4],
            [3, 0, 4],
            [2, 0, 5],
            [1, 2, 5],
            [3, 1, 5],
            [0, 3, 5],
        ],
    );
    let out = run(&octa, 0);
    assert!(out.faces.len() >= 4 && boundary_edges(&out).is_empty(), "{out:?}");
}

#[test]
fn non_manifold_spine_is_kept() {
    // Three 6 x 6 sheets sharing their left column, the z axis: its six edges have
    // three faces each.
    let n = 6;
    let mut m = Mesh::default();
    m.positions.extend((0..=n).map(|j| [0.0, 0.0, j as f64 / n as f64]));
    for k in 0..3 {
        let (s, c) = (2.0 * std::f64::consts::PI * k as f64 / 3.0).sin_cos();
        let base = m.positions.len() as u32;
        for j in 0..=n {
            for i in 1..=n {
                let r = i as f64 / n as f64;
                m.positions.push([r * c, r * s, j as f64 / n as f64]);
            }
        }
        let id = |i: u32, j: u32| if i == 0 { j } else { base + j * n + i - 1 };
        for j in 0..n {
            for i in 0..n {
                let q = [id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)];
                m.faces.extend([[q[0], q[1], q[2]], [q[0], q[2], q[3]]]);
            }
        }
    }
    let out = run(&m, m.faces.len() / 3);
    assert!(out.faces.len() <= m.faces.len() / 3);
    let fins: Vec<_> =
        edge_face_counts(&out).into_iter().filter(|&(_, n)| n > 2).map(|(e, _)| e).collect();
    assert!(!fins.is_empty(), "the non-manifold spine was collapsed away");
    for v in fins.iter().flat_map(|&(u, v)| [u, v]) {
        let p = out.positions[v as usize];
        assert!(p[0].abs() < 1e-9 && p[1].abs() < 1e-9, "the spine left its line: {p:?}");
    }
    for end in [[0.0, 0.0, 0.0], [0.0, 0.0, 1.0]] {
        assert!(
            out.positions.iter().any(|&p| dist2(p, end) < 1e-18),
            "spine end {end:?} moved"
        );
    }
}

#[test]
fn target_above_the_face_count_only_cleans() {
    let input = grid(4);
    assert_eq!(run(&input, 1000), input);
}

mod shared_data {
    use super::*;

    #[test]
    #[ignore = "needs ../shared/data"]
    fn basketball_frame_decimates_to_an_eighth() {
        let input = crate::shared_data::read_obj("basketball_player/basketball_player_fr0011.obj");
        let target = input.faces.len() / 8;
        let start = std::time::Instant::now();
        let out = decimate(&input.positions, &input.faces, target);
        let elapsed = start.elapsed();
        assert_valid(&out);
        assert!(out.faces.len() <= target, "{} faces for target {target}", out.faces.len());
        assert_eq!(components(&out), components(&input), "a component vanished");
        assert_eq!(decimate(&input.positions, &input.faces, target), out, "not deterministic");
        println!(
            "basketball fr0011: {} -> {} faces, {} -> {} vertices, {} -> {} components, in {:.1} ms",
            input.faces.len(),
            out.faces.len(),
            input.positions.len(),
            out.positions.len(),
            components(&input),
            components(&out),
            elapsed.as_secs_f64() * 1e3
        );
    }
}
