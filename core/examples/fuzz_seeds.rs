//! Writes the seed inputs of the fuzz targets (`dynmesh::fuzzing::seeds`) into
//! `DIR/<target>/seed_N`, the corpus layout cargo fuzz reads:
//! `cargo run --release -p dynmesh --features fuzzing --example fuzz_seeds -- fuzz/corpus`.

fn main() -> std::io::Result<()> {
    let dir = std::path::PathBuf::from(std::env::args().nth(1).unwrap_or_else(|| "fuzz/corpus".into()));
    for (i, (target, data)) in dynmesh::fuzzing::seeds().into_iter().enumerate() {
        std::fs::create_dir_all(dir.join(target))?;
        std::fs::write(dir.join(target).join(format!("seed_{i}")), data)?;
    }
    Ok(())
}
