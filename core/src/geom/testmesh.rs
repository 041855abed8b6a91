//! Meshes built by the tests of the geometry kernels and of the stages that use them.

use crate::geom::mesh::{add, normalize, scale};
use std::collections::HashMap;

/// xorshift64*: reproducible pseudo-random numbers without a dependency.
pub struct Rng(pub u64);

impl Rng {
    pub fn unit(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
    }

    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }

    pub fn point(&mut self, lo: f64, hi: f64) -> [f64; 3] {
        [self.range(lo, hi), self.range(lo, hi), self.range(lo, hi)]
    }
}

pub type Soup = (Vec<[f64; 3]>, Vec<[u32; 3]>);

/// Latitude-longitude sphere with pole fans, outward CCW: `2 * slices * (stacks - 1)`
/// triangles; `radius(theta, phi)` shapes it.
pub fn uv_sphere(stacks: u32, slices: u32, radius: impl Fn(f64, f64) -> f64) -> Soup {
    use std::f64::consts::PI;
    let mut pos = vec![[0.0, 0.0, radius(0.0, 0.0)]];
    for i in 1..stacks {
        let th = PI * i as f64 / stacks as f64;
        for j in 0..slices {
            let ph = 2.0 * PI * j as f64 / slices as f64;
            let r = radius(th, ph);
            pos.push([r * th.sin() * ph.cos(), r * th.sin() * ph.sin(), r * th.cos()]);
        }
    }
    pos.push([0.0, 0.0, -radius(PI, 0.0)]);
    let ring = |i: u32, j: u32| 1 + (i - 1) * slices + j % slices;
    let south = pos.len() as u32 - 1;
    let mut faces = Vec::new();
    for j in 0..slices {
        faces.push([0, ring(1, j), ring(1, j + 1)]);
        faces.push([south, ring(stacks - 1, j + 1), ring(stacks - 1, j)]);
        for i in 1..stacks - 1 {
            let (a, b) = (ring(i, j), ring(i, j + 1));
            let (c, d) = (ring(i + 1, j), ring(i + 1, j + 1));
            faces.push([a, c, d]);
            faces.push([a, d, b]);
        }
    }
    (pos, faces)
}

/// Icosahedron on the sphere of `radius`, midpoint-subdivided `levels` times with the new
/// vertices pushed onto the sphere.
pub fn icosphere(levels: u32, radius: f64) -> Soup {
    let p = (1.0 + 5f64.sqrt()) / 2.0;
    let raw = [
        [-1.0, p, 0.0], [1.0, p, 0.0], [-1.0, -p, 0.0], [1.0, -p, 0.0],
        [0.0, -1.0, p], [0.0, 1.0, p], [0.0, -1.0, -p], [0.0, 1.0, -p],
        [p, 0.0, -1.0], [p, 0.0, 1.0], [-p, 0.0, -1.0], [-p, 0.0, 1.0],
    ];
    let mut soup = (
        raw.iter().map(|&v| scale(normalize(v), radius)).collect(),
        vec![
            [0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
            [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8],
            [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1],
        ],
    );
    for _ in 0..levels {
        soup = midpoint(&soup, 1);
        soup.0.iter_mut().for_each(|v| *v = scale(normalize(*v), radius));
    }
    soup
}

/// Flat midpoint subdivision, `levels` times (what the codec does to its base mesh).
pub fn midpoint(soup: &Soup, levels: u32) -> Soup {
    let (mut pos, mut faces) = soup.clone();
    for _ in 0..levels {
        let mut mid = HashMap::new();
        let mut split = |a: u32, b: u32, pos: &mut Vec<[f64; 3]>| {
            *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                pos.push(scale(add(pos[a as usize], pos[b as usize]), 0.5));
                pos.len() as u32 - 1
            })
        };
        let mut next = Vec::with_capacity(faces.len() * 4);
        for [a, b, c] in faces {
            let ab = split(a, b, &mut pos);
            let (bc, ca) = (split(b, c, &mut pos), split(c, a, &mut pos));
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        faces = next;
    }
    (pos, faces)
}

/// `nx` x `ny` vertex grid with spacing `h` from `origin` in the plane z = origin z,
/// normal +z.
pub fn grid(nx: u32, ny: u32, h: f64, origin: [f64; 3]) -> Soup {
    let pos = (0..ny)
        .flat_map(|j| (0..nx).map(move |i| add(origin, [i as f64 * h, j as f64 * h, 0.0])))
        .collect();
    let mut faces = Vec::new();
    for j in 0..ny - 1 {
        for i in 0..nx - 1 {
            let v = j * nx + i;
            faces.push([v, v + 1, v + nx + 1]);
            faces.push([v, v + nx + 1, v + nx]);
        }
    }
    (pos, faces)
}

/// `n` x `n` quads of a wavy sheet over [-1, 1]^2 facing +z, with UV = position mapped to
/// [0, 1]^2: (positions, faces, one UV per vertex).
pub fn wavy_sheet(n: u32) -> (Soup, Vec<[f64; 2]>) {
    let s = 2.0 / n as f64;
    let p: Vec<[f64; 3]> = (0..=n)
        .flat_map(|j| (0..=n).map(move |i| (i as f64 * s - 1.0, j as f64 * s - 1.0)))
        .map(|(x, y)| [x, y, 0.2 * (3.0 * x).sin() * (2.0 * y).cos()])
        .collect();
    let uv = p.iter().map(|q| [0.5 * (q[0] + 1.0), 0.5 * (q[1] + 1.0)]).collect();
    let at = |i: u32, j: u32| j * (n + 1) + i;
    let f = (0..n)
        .flat_map(|j| (0..n).map(move |i| (i, j)))
        .flat_map(|(i, j)| [[at(i, j), at(i + 1, j), at(i + 1, j + 1)], [at(i, j), at(i + 1, j + 1), at(i, j + 1)]])
        .collect();
    ((p, f), uv)
}
