//! Writes a synthetic mesh of about N triangles as binary PLY, for measuring bakes of meshes
//! larger than any in the repository (docs/performance.md, memory against vertex count):
//! a square grid of bumps and pits (every vertex partly shadowed by its neighbours).
//!
//!     cargo run --release --example synthetic_mesh -- 10000000 /tmp/grid10m.ply

use std::io::Write;

fn main() {
    let mut args = std::env::args().skip(1);
    let usage = "usage: synthetic_mesh TRIANGLES OUTPUT.ply";
    let triangles: u64 = args.next().and_then(|a| a.parse().ok()).expect(usage);
    let output = args.next().expect(usage);
    // A side of s cells has 2 s^2 triangles and (s + 1)^2 vertices.
    let side = ((triangles as f64 / 2.0).sqrt().ceil() as u32).max(1);
    let n = side + 1;
    let file = std::fs::File::create(&output).expect("create the output");
    let mut out = std::io::BufWriter::new(file);
    write!(
        out,
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\n\
         property float y\nproperty float z\nelement face {}\n\
         property list uchar uint vertex_indices\nend_header\n",
        n as u64 * n as u64,
        2 * side as u64 * side as u64
    )
    .unwrap();
    for j in 0..n {
        for i in 0..n {
            let (u, v) = (i as f32 / side as f32, j as f32 / side as f32);
            let bumps = 24.0 * std::f32::consts::PI;
            let height = 0.02 * (bumps * u).sin() * (bumps * v).cos();
            for x in [u - 0.5, height, v - 0.5] {
                out.write_all(&x.to_le_bytes()).unwrap();
            }
        }
    }
    for j in 0..side {
        for i in 0..side {
            let corner = j * n + i;
            for tri in [
                [corner, corner + n, corner + 1],
                [corner + 1, corner + n, corner + n + 1],
            ] {
                out.write_all(&[3u8]).unwrap();
                for index in tri {
                    out.write_all(&index.to_le_bytes()).unwrap();
                }
            }
        }
    }
    out.flush().unwrap();
    eprintln!(
        "{output}: {} vertices, {} triangles",
        n * n,
        2 * side * side
    );
}
