//! Times loading and projecting an environment map:
//! `cargo run --release --example project_envmap -- MAP.exr [BANDS] [RUNS]`.

use prt_gpu::light::{envmap, project, Mapping};
use std::path::PathBuf;
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let path = PathBuf::from(
        args.next()
            .ok_or("usage: project_envmap MAP [BANDS] [RUNS]")?,
    );
    let bands: u32 = args.next().map(|s| s.parse()).transpose()?.unwrap_or(4);
    let runs: usize = args.next().map(|s| s.parse()).transpose()?.unwrap_or(10);

    let start = Instant::now();
    let image = envmap::load(&path)?;
    let load_ms = start.elapsed().as_secs_f64() * 1e3;
    let mapping = Mapping::detect(image.width, image.height)?;

    let mut times = Vec::new();
    let mut light = None;
    for _ in 0..runs.max(1) {
        let start = Instant::now();
        light = Some(project(&image, mapping, bands)?);
        times.push(start.elapsed().as_secs_f64() * 1e3);
    }
    times.sort_by(f64::total_cmp);
    let light = light.ok_or("no run")?;
    println!(
        "{}: {}x{} {}, load {load_ms:.1} ms; project {bands} bands: min {:.2} ms, median {:.2} ms over {} runs; rayon threads {}",
        path.display(),
        image.width,
        image.height,
        mapping.name(),
        times[0],
        times[times.len() / 2],
        times.len(),
        rayon::current_num_threads()
    );
    println!("l_00 = {:?}", light.coeffs[0]);
    Ok(())
}
