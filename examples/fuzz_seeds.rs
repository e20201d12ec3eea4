//! Writes the hostile-file seeds (`prt_gpu::testing::seeds`) as the fuzzers' first corpus,
//! `fuzz/corpus/<reader>/<seed>`: `cargo run --release --example fuzz_seeds`. The suite
//! mutates the same seeds, and reads back whatever the corpus holds.

use std::path::Path;

use prt_gpu::testing::hostile::Reader;
use prt_gpu::testing::seeds::seeds;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let scratch = tempfile::tempdir()?;
    for reader in Reader::ALL {
        let dir = root.join("fuzz/corpus").join(reader.name());
        std::fs::create_dir_all(&dir)?;
        for (name, bytes) in seeds(reader, &root.join("tests/data"), scratch.path())? {
            std::fs::write(dir.join(format!("seed-{name}")), bytes)?;
        }
        println!("{}", dir.display());
    }
    Ok(())
}
