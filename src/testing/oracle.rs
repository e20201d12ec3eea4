//! The independent oracle of the accuracy tests: exit radiance at surface points path traced by
//! Mitsuba 3 (pip `mitsuba`), through `tests/oracle/mitsuba_oracle.py`.
//!
//! Mitsuba shares nothing with the baker: not the BVH, the sampling, the SH code, the gather
//! matrix or the depth maps. It is handed the prepared scene (positions, the very shading
//! normals the baker used, per-vertex albedo, triangles), a light, and the points to measure;
//! it answers each point's mean radiance over its paths and that mean's standard error.
//!
//! Where python3 with Mitsuba is missing, [`path_trace`] says why and gives `None`, except under
//! CI (`CI` set), where `ci/test.sh` installs it: a panic.

use std::path::{Path, PathBuf};
use std::process::Command;

use glam::Vec3;

use crate::scene::Scene;

/// A light the oracle renders.
#[derive(Clone, Debug)]
pub enum OracleLight {
    /// Radiant intensity `intensity` W/sr in every direction.
    Point { position: Vec3, intensity: f32 },
    /// A point light lit only inside a cone of half angle `half_angle_degrees` (a hard edge).
    Spot {
        position: Vec3,
        direction: Vec3,
        half_angle_degrees: f32,
        intensity: f32,
    },
    /// Distant light `L(w) = sum_k c_k y_k(w)` in the baker's SH convention, RGB per
    /// coefficient: a band-limited sky, exact for a bake of at least `bands` bands.
    Sky { bands: u32, coefficients: Vec<Vec3> },
}

/// A point where the oracle measures exit radiance: on the face `face` of the scene, with the
/// shading normal the baker used there.
#[derive(Clone, Copy, Debug)]
pub struct SurfacePoint {
    pub position: Vec3,
    pub normal: Vec3,
    pub face: u32,
}

/// What the oracle answered.
#[derive(Clone, Debug)]
pub struct OracleRadiance {
    pub radiance: Vec<Vec3>,
    /// The standard error of each mean over its paths.
    pub standard_error: Vec<Vec3>,
    /// Mitsuba's variant (`llvm_ad_rgb` or `scalar_rgb`) and version, and its seconds.
    pub variant: String,
    pub seconds: f64,
}

/// The script, beside the tests.
pub fn script() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/oracle/mitsuba_oracle.py")
}

/// Each vertex of a prepared scene as a point on one of its faces (the first that uses it).
pub fn vertex_points(scene: &Scene) -> Vec<SurfacePoint> {
    let normals = scene
        .normals
        .as_deref()
        .expect("a prepared scene has normals");
    let mut face = vec![u32::MAX; scene.positions.len()];
    for (t, triangle) in scene.triangles.iter().enumerate() {
        for &v in triangle {
            if face[v as usize] == u32::MAX {
                face[v as usize] = t as u32;
            }
        }
    }
    (0..scene.positions.len())
        .filter(|&v| face[v] != u32::MAX)
        .map(|v| SurfacePoint {
            position: scene.positions[v],
            normal: normals[v],
            face: face[v],
        })
        .collect()
}

/// Whether the oracle can run; where it cannot, a printed reason and `false`, except under CI.
pub fn available() -> bool {
    super::python_with(&["numpy", "mitsuba"])
}

/// Exit radiance at `points` of `scene` under `light` after `bounces` bounces (0: direct light
/// only), `samples` paths per point. `None` where [`available`] is false.
pub fn path_trace(
    scene: &Scene,
    points: &[SurfacePoint],
    light: &OracleLight,
    bounces: u32,
    samples: u32,
) -> Option<OracleRadiance> {
    let query = serde_json::json!({"query": "exit", "bounces": bounces});
    run_job(scene, points, light, query, samples)
}

/// A homogeneous medium behind a smooth dielectric boundary (the mesh's surface), its
/// coefficients per scene unit, scattering isotropic.
#[derive(Clone, Copy, Debug)]
pub struct OracleMedium {
    pub absorption: Vec3,
    pub scattering: Vec3,
    pub ior: f32,
}

/// Exit radiance at `points` of `scene`, the boundary of `medium`, under `light`: volumetric
/// path tracing of the light that enters, scatters and leaves (and of what the smooth surface
/// reflects), up to `events` scattering and surface events a path (Russian roulette past 64),
/// `samples` paths per point. `None` where [`available`] is false.
pub fn path_trace_medium(
    scene: &Scene,
    points: &[SurfacePoint],
    light: &OracleLight,
    (medium, events): (OracleMedium, u32),
    samples: u32,
) -> Option<OracleRadiance> {
    let query = serde_json::json!({
        "query": "exit",
        "bounces": events,
        "medium": {
            "sigma_a": medium.absorption.to_array(),
            "sigma_s": medium.scattering.to_array(),
            "ior": medium.ior,
        },
    });
    run_job(scene, points, light, query, samples)
}

/// Irradiance at free points of space (a probe's, not on the surface) for surfaces of the
/// given normals (`SurfacePoint::face` unused), from `samples` cosine-distributed paths each:
/// the sky seen directly, plus light the scene reflects up to `reflections` times on its way
/// (0: the sky alone, the scene a black occluder). `None` where [`available`] is false.
pub fn irradiance(
    scene: &Scene,
    points: &[SurfacePoint],
    light: &OracleLight,
    reflections: u32,
    samples: u32,
) -> Option<OracleRadiance> {
    let query = serde_json::json!({"query": "irradiance", "reflections": reflections});
    run_job(scene, points, light, query, samples)
}

fn run_job(
    scene: &Scene,
    points: &[SurfacePoint],
    light: &OracleLight,
    query: serde_json::Value,
    samples: u32,
) -> Option<OracleRadiance> {
    if !available() {
        return None;
    }
    let scratch = super::Scratch::new();
    let dir = &scratch.0;
    write_job(dir, scene, points, light, query, samples);
    let mut command = Command::new("python3");
    command.arg(script()).arg(dir);
    if std::env::var_os("DRJIT_LIBLLVM_PATH").is_none() {
        if let Some(llvm) = find_libllvm() {
            command.env("DRJIT_LIBLLVM_PATH", llvm);
        }
    }
    let out = command.output().expect("run python3");
    assert!(
        out.status.success(),
        "the Mitsuba oracle failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let said: serde_json::Value =
        serde_json::from_slice(&out.stdout).expect("the oracle prints JSON");
    if let Some(keep) = std::env::var_os("PRT_GPU_ORACLE_KEEP") {
        // For looking into a disagreement by hand: the job as the oracle saw it.
        let _ = std::fs::remove_dir_all(&keep);
        let _ = std::process::Command::new("cp")
            .arg("-r")
            .arg(dir)
            .arg(&keep)
            .status();
    }
    let radiance = read_vec3s(&dir.join("radiance.f32"));
    let standard_error = read_vec3s(&dir.join("stderr.f32"));
    assert_eq!(radiance.len(), points.len());
    Some(OracleRadiance {
        radiance,
        standard_error,
        variant: format!(
            "{} {}",
            said["variant"].as_str().unwrap_or("?"),
            said["mitsuba"].as_str().unwrap_or("?")
        ),
        seconds: said["seconds"].as_f64().unwrap_or(0.0),
    })
}

/// Debian's libLLVM for Dr.Jit's LLVM backend (the vectorised variant): the 19 that
/// `ci/test.sh` installs, else any other found.
fn find_libllvm() -> Option<PathBuf> {
    let dir = Path::new("/usr/lib/x86_64-linux-gnu");
    let pinned = dir.join("libLLVM.so.19.1");
    if pinned.exists() {
        return Some(pinned);
    }
    let mut found: Vec<PathBuf> = std::fs::read_dir(dir)
        .ok()?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with("libLLVM") && n.contains(".so"))
        })
        .collect();
    found.pop()
}

fn write_floats(path: &Path, values: impl Iterator<Item = f32>) {
    let bytes: Vec<u8> = values.flat_map(f32::to_le_bytes).collect();
    std::fs::write(path, bytes).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
}

fn write_u32s(path: &Path, values: impl Iterator<Item = u32>) {
    let bytes: Vec<u8> = values.flat_map(u32::to_le_bytes).collect();
    std::fs::write(path, bytes).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
}

fn vec3s(values: &[Vec3]) -> impl Iterator<Item = f32> + '_ {
    values.iter().flat_map(|v| v.to_array())
}

fn read_vec3s(path: &Path) -> Vec<Vec3> {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    bytes
        .chunks_exact(12)
        .map(|c| {
            let f = |i: usize| f32::from_le_bytes(c[4 * i..4 * i + 4].try_into().expect("4 bytes"));
            Vec3::new(f(0), f(1), f(2))
        })
        .collect()
}

fn light_json(light: &OracleLight) -> serde_json::Value {
    use serde_json::json;
    match light {
        OracleLight::Point {
            position,
            intensity,
        } => json!({"type": "point", "position": position.to_array(), "intensity": intensity}),
        OracleLight::Spot {
            position,
            direction,
            half_angle_degrees,
            intensity,
        } => json!({
            "type": "spot",
            "position": position.to_array(),
            "direction": direction.to_array(),
            "half_angle_degrees": half_angle_degrees,
            "intensity": intensity,
        }),
        OracleLight::Sky {
            bands,
            coefficients,
        } => json!({
            "type": "sh",
            "bands": bands,
            "coefficients": coefficients.iter().map(|c| c.to_array()).collect::<Vec<_>>(),
        }),
    }
}

fn write_job(
    dir: &Path,
    scene: &Scene,
    points: &[SurfacePoint],
    light: &OracleLight,
    query: serde_json::Value,
    samples: u32,
) {
    let normals = scene
        .normals
        .as_deref()
        .expect("a prepared scene has normals");
    write_floats(&dir.join("positions.f32"), vec3s(&scene.positions));
    write_floats(&dir.join("normals.f32"), vec3s(normals));
    write_floats(&dir.join("albedo.f32"), vec3s(&scene.albedo));
    write_u32s(
        &dir.join("triangles.u32"),
        scene.triangles.iter().flatten().copied(),
    );
    let positions: Vec<Vec3> = points.iter().map(|p| p.position).collect();
    let query_normals: Vec<Vec3> = points.iter().map(|p| p.normal).collect();
    write_floats(&dir.join("points.f32"), vec3s(&positions));
    write_floats(&dir.join("qnormals.f32"), vec3s(&query_normals));
    write_u32s(&dir.join("qfaces.u32"), points.iter().map(|p| p.face));
    let mut job = serde_json::json!({
        "vertices": scene.positions.len(),
        "faces": scene.triangles.len(),
        "points": points.len(),
        "positions": "positions.f32",
        "normals": "normals.f32",
        "albedo": "albedo.f32",
        "triangles": "triangles.u32",
        "query_points": "points.f32",
        "query_normals": "qnormals.f32",
        "query_faces": "qfaces.u32",
        "light": light_json(light),
        "samples": samples,
        "seed": 1,
    });
    if let (Some(job), Some(query)) = (job.as_object_mut(), query.as_object()) {
        job.extend(query.clone());
    }
    std::fs::write(dir.join("job.json"), job.to_string()).expect("write the oracle's job");
}

/// Which vertices the oracle can be compared with one to one, by a rule of geometry alone
/// (nothing of the baker's): a vertex whose shading normal is within `crease_degrees` of the
/// geometric normal of every face around it (at a crease its radiance is the limit of no
/// face's, and the path tracer's query lands on one of them), and that touches no triangle
/// other than its own within `1e-5` of the scene's extent (a vertex on the line where a
/// cabinet meets a wall is half hidden, its radiance there a step).
pub fn measurable_vertices(scene: &Scene, crease_degrees: f32) -> Vec<bool> {
    let normals = scene
        .normals
        .as_deref()
        .expect("a prepared scene has normals");
    let cos = crease_degrees.to_radians().cos();
    let mut keep = vec![true; scene.positions.len()];
    for triangle in &scene.triangles {
        let [a, b, c] = triangle.map(|i| scene.positions[i as usize]);
        let face = (b - a).cross(c - a).normalize_or_zero();
        for &v in triangle {
            if normals[v as usize].dot(face) < cos {
                keep[v as usize] = false;
            }
        }
    }
    let touching = vertices_touching_other_triangles(scene);
    keep.iter_mut()
        .zip(touching)
        .for_each(|(k, touches)| *k &= !touches);
    keep
}

/// Per vertex, whether a triangle that does not use it passes within `1e-5` of the extent.
fn vertices_touching_other_triangles(scene: &Scene) -> Vec<bool> {
    use std::collections::HashMap;
    let (lo, hi) = scene.positions.iter().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), &p| (lo.min(p), hi.max(p)),
    );
    let extent = (hi - lo).max_element().max(f32::MIN_POSITIVE);
    let epsilon = 1e-5 * extent;
    let cell = extent / 64.0;
    let key = |p: Vec3| ((p - lo) / cell).floor().as_ivec3().to_array();
    let mut cells: HashMap<[i32; 3], Vec<u32>> = HashMap::new();
    for (t, triangle) in scene.triangles.iter().enumerate() {
        let corners = triangle.map(|i| scene.positions[i as usize]);
        let min = corners[0].min(corners[1]).min(corners[2]) - epsilon;
        let max = corners[0].max(corners[1]).max(corners[2]) + epsilon;
        let (a, b) = (key(min), key(max));
        for x in a[0]..=b[0] {
            for y in a[1]..=b[1] {
                for z in a[2]..=b[2] {
                    cells.entry([x, y, z]).or_default().push(t as u32);
                }
            }
        }
    }
    scene
        .positions
        .iter()
        .enumerate()
        .map(|(v, &p)| {
            cells.get(&key(p)).is_some_and(|near| {
                near.iter().any(|&t| {
                    let triangle = scene.triangles[t as usize];
                    !triangle.contains(&(v as u32))
                        && distance_to_triangle(p, triangle.map(|i| scene.positions[i as usize]))
                            <= epsilon
                })
            })
        })
        .collect()
}

/// The distance from `p` to the triangle `[a, b, c]` (its closest point by the regions of
/// the triangle's plane: a corner, an edge, or the inside).
pub fn distance_to_triangle(p: Vec3, [a, b, c]: [Vec3; 3]) -> f32 {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return p.distance(a);
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return p.distance(b);
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return p.distance(a + ab * (d1 / (d1 - d3)));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return p.distance(c);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return p.distance(a + ac * (d2 / (d2 - d6)));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return p.distance(b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6))));
    }
    let denom = 1.0 / (va + vb + vc);
    p.distance(a + ab * (vb * denom) + ac * (vc * denom))
}

/// Relative RMS error of `ours` against the oracle over the kept points, `sqrt(sum |e|^2 /
/// sum |truth|^2)`, and the oracle's own share of it, `sqrt(sum se^2 / sum |truth|^2)`: what
/// the error would read were the baker exact.
pub fn relative_rms(ours: &[Vec3], oracle: &OracleRadiance, keep: &[bool]) -> (f64, f64) {
    let (mut error, mut noise, mut norm) = (0.0f64, 0.0f64, 0.0f64);
    for (i, &k) in keep.iter().enumerate() {
        if k {
            error += (ours[i] - oracle.radiance[i]).length_squared() as f64;
            noise += oracle.standard_error[i].length_squared() as f64;
            norm += oracle.radiance[i].length_squared() as f64;
        }
    }
    let norm = norm.max(f64::MIN_POSITIVE);
    ((error / norm).sqrt(), (noise / norm).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distance_to_a_triangle_by_region() {
        let t = [Vec3::ZERO, Vec3::X, Vec3::Y];
        assert!((distance_to_triangle(Vec3::new(0.25, 0.25, 2.0), t) - 2.0).abs() < 1e-6);
        assert!((distance_to_triangle(Vec3::new(-1.0, -1.0, 0.0), t) - 2f32.sqrt()).abs() < 1e-6);
        assert!((distance_to_triangle(Vec3::new(0.5, -3.0, 0.0), t) - 3.0).abs() < 1e-6);
        let beyond_hypotenuse = distance_to_triangle(Vec3::new(1.0, 1.0, 0.0), t);
        assert!((beyond_hypotenuse - 0.5f32.sqrt()).abs() < 1e-6);
    }

    #[test]
    fn creases_and_contacts_are_not_measured() {
        use crate::scene::{builtin, prepare::prepare};
        // A box resting on a plane: the box's vertices have smoothed normals at its edges (not
        // measurable), and its bottom face touches the plane (its vertices, and the plane's
        // under it, are not measurable); the plane's vertices away from it are.
        let plane = builtin::grid_plane(Vec3::ZERO, Vec3::Z * 2.0, Vec3::X * 2.0, 8, Vec3::ONE);
        let cube = builtin::closed_box(Vec3::new(-0.5, 0.0, -0.5), Vec3::new(0.5, 1.0, 0.5), 2);
        let (scene, _) = prepare(builtin::merge(&[plane, cube])).unwrap();
        let keep = measurable_vertices(&scene, 10.0);
        for (v, &p) in scene.positions.iter().enumerate() {
            let on_cube = p.x.abs() <= 0.5 && p.z.abs() <= 0.5 && p.y >= 0.0;
            let face_centre_of_cube_top = p == Vec3::new(0.0, 1.0, 0.0);
            if face_centre_of_cube_top || (p.y == 0.0 && !on_cube) {
                assert!(keep[v], "{p} should be measured");
            }
            if on_cube && !face_centre_of_cube_top && p.y == 0.0 {
                assert!(!keep[v], "{p} touches the plane or the box");
            }
        }
    }
}
