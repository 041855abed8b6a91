//! The real captures some tests measure on: `shared/data` beside the repository, found relative
//! to it as the Python tests find it (`tests/conftest.py`), and absent from a user's checkout.
//!
//! A test that needs it lives in a `shared_data` module and carries
//! `#[ignore = "needs ../shared/data"]`: `cargo test` lists it as ignored, with that reason,
//! whether or not the data is there, and `cargo test -p dynmesh --release -- --ignored
//! shared_data` runs exactly these tests. Run without the data, such a test fails naming the
//! missing path instead of passing without having measured anything.

use std::path::{Path, PathBuf};

use crate::geom::mesh::Mesh;

/// `<repository>/../shared/data`.
pub fn dir() -> PathBuf {
    // The crate lives in `<repository>/core`; its grandparent is the folder holding the repository.
    let beside = Path::new(env!("CARGO_MANIFEST_DIR")).ancestors().nth(2).unwrap_or(Path::new(".."));
    beside.join("shared/data")
}

/// Positions and faces of the OBJ file at `relative` (e.g.
/// `"basketball_player/basketball_player_fr0011.obj"`) in the shared data: `v` records and `f`
/// records (1-based, `v/vt/vn` forms allowed, polygons split into fans); the rest is ignored, as
/// the shared captures need nothing more. Panics naming the file if it is missing or malformed.
pub fn read_obj(relative: &str) -> Mesh {
    let path = dir().join(relative);
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| {
        panic!("this test needs ../shared/data beside the repository: {}: {e}", path.display())
    });
    let bad = |line: &str| -> ! { panic!("{}: unreadable line {line:?}", path.display()) };
    let mut mesh = Mesh::default();
    for line in text.lines() {
        let mut fields = line.split_whitespace();
        match fields.next() {
            Some("v") => {
                let c: Vec<f64> = fields.take(3).map_while(|s| s.parse().ok()).collect();
                let &[x, y, z] = c.as_slice() else { bad(line) };
                mesh.positions.push([x, y, z]);
            }
            Some("f") => {
                let corner = |s: &str| s.split('/').next()?.parse::<u32>().ok()?.checked_sub(1);
                let Some(v) = fields.map(corner).collect::<Option<Vec<u32>>>() else { bad(line) };
                if v.len() < 3 {
                    bad(line);
                }
                mesh.faces.extend((1..v.len() - 1).map(|k| [v[0], v[k], v[k + 1]]));
            }
            _ => {}
        }
    }
    mesh
}
