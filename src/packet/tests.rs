//! The packet traversals against the single-ray reference, every compiled copy of them.

use super::*;
use crate::ray::{Ray, RAY_T_MAX};
use crate::sampling::Pcg32;
use crate::scene::{self, builtin, prepare::prepare};
use glam::Vec3;

/// A mesh's BVH and its vertices as ray origins (moved off the surface) with their normals:
/// what the packet tests cast from, built here from `scene` and `bvh` alone.
struct Surface {
    bvh: Bvh,
    origins: Vec<Vec3>,
    normals: Vec<Vec3>,
}

impl Surface {
    /// The prepared mesh `tests/data/<name>`.
    fn load(name: &str) -> Surface {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/data")
            .join(name);
        let (mesh, _) = prepare(scene::load(&path).unwrap()).unwrap();
        let bvh = Bvh::build(&mesh.positions, &mesh.triangles);
        let normals = mesh.normals.clone().expect("a prepared mesh has normals");
        let extent = bvh.extent();
        let origins = mesh
            .positions
            .iter()
            .zip(&normals)
            .map(|(&p, &n)| crate::ray::offset_ray_origin(p, n, extent))
            .collect();
        Surface {
            bvh,
            origins,
            normals,
        }
    }
}

fn random_direction(rng: &mut Pcg32) -> Vec3 {
    loop {
        let v = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
        if (0.01..=1.0).contains(&v.length_squared()) {
            return v.normalize();
        }
    }
}

/// The any-hit query through one copy of the traversal.
fn any_hit<P: Packet>(
    copy: dispatch::Copy<P, Blocked>,
    bvh: &Bvh,
    packet: &P,
    path: &PointPath,
    t_max: f32,
) -> LaneMask {
    let mut query = Blocked { t_max, blocked: 0 };
    copy(bvh, packet, path, &mut query);
    query.blocked
}

/// Runs every copy of the traversal on `packet`, once down each of `paths`: every answer must
/// be the first and no inactive lane reported. Returns (lanes compared, lanes that differ from
/// `expected`, lanes blocked).
fn check_copies<P: Packet>(
    copies: &[(&'static str, dispatch::Copy<P, Blocked>)],
    (bvh, paths): (&Bvh, &[&PointPath]),
    packet: &P,
    above: LaneMask,
    expected: LaneMask,
) -> [usize; 3] {
    let answers: Vec<(&str, LaneMask)> = (copies.iter())
        .flat_map(|&(name, f)| paths.iter().map(move |path| (name, f, path)))
        .map(|(name, f, path)| (name, any_hit(f, bvh, packet, path, RAY_T_MAX)))
        .collect();
    let first = answers[0].1;
    for &(name, got) in &answers {
        assert_eq!(
            got, first,
            "{name} differs from the portable copy from the root"
        );
        assert_eq!(got & !above, 0, "{name}: an inactive lane reported a hit");
    }
    [above, first ^ expected, expected].map(|m| m.count_ones() as usize)
}

/// Every copy of the traversal against single rays, on packets of `width` consecutive
/// (Morton-adjacent) vertices and random directions, lanes above the horizon active.
/// Returns (lanes compared, lanes that differ, lanes blocked).
fn compare_with_single_rays(inputs: &Surface, width: usize, packets: usize) -> [usize; 3] {
    let mut rng = Pcg32::new(7);
    let mut counts = [0; 3];
    for _ in 0..packets {
        // (Per packet: a copy's type names the packet's borrow of its origins.)
        let copies = dispatch::all_available();
        let count = inputs.origins.len();
        let start = (rng.next_u32() as usize) % (count - width + 1);
        let origins = PacketOrigins::new(&inputs.origins[start..start + width]);
        let direction = random_direction(&mut rng);
        let normals = &inputs.normals[start..start + width];
        let above = lane_mask(|l| l < width && normals[l].dot(direction) > 0.0);
        let packet = RayPacket::new(&origins, direction, above);
        let expected = lane_mask(|l| {
            above & (1 << l) != 0 && inputs.bvh.occluded(&packet.lane_ray(l), RAY_T_MAX)
        });
        let from_root = (&inputs.bvh, &[&PointPath::NONE][..]);
        let checked = check_copies(&copies, from_root, &packet, above, expected);
        counts.iter_mut().zip(checked).for_each(|(c, n)| *c += n);
    }
    counts
}

#[test]
fn packets_agree_with_single_rays_on_the_dragon() {
    let inputs = Surface::load("dragon_vrip_res3.ply.gz");
    let [lanes, differ, blocked] = compare_with_single_rays(&inputs, LANES, 20_000);
    println!(
        "dragon: {lanes} lanes, {blocked} blocked, {differ} differ from single rays \
         ({:.5}% identical)",
        100.0 * (lanes - differ) as f64 / lanes as f64
    );
    assert!(
        blocked > lanes / 10,
        "too few blocked rays to test anything"
    );
    assert_eq!(differ, 0);
}

#[test]
fn packets_agree_with_single_rays_on_the_bunny_and_partial_packets() {
    let inputs = Surface::load("bunny.obj");
    for width in [1, 5, LANES - 1, LANES] {
        let [lanes, differ, blocked] = compare_with_single_rays(&inputs, width, 4_000);
        println!("bunny, {width} lanes: {lanes} lanes, {blocked} blocked, {differ} differ");
        assert!(blocked > 0);
        assert_eq!(differ, 0, "{width}-lane packets");
    }
}

/// A random vertex of `inputs` and `width` consecutive samples of `set` from a random start,
/// turned into the vertex's tangent frame.
fn random_fan(
    inputs: &Surface,
    set: &crate::sampling::SampleSet,
    width: usize,
    rng: &mut Pcg32,
) -> (usize, Vec<Vec3>) {
    let vertex = (rng.next_u32() as usize) % inputs.origins.len();
    let start = (rng.next_u32() as usize) % (set.len() - width + 1);
    let to_world = crate::sampling::VertexDirections::new(set.frame, inputs.normals[vertex]);
    let directions = set.directions[start..start + width]
        .iter()
        .map(|&d| to_world.world(d))
        .collect();
    (vertex, directions)
}

/// Every copy of the fan traversal against single rays: packets of `width` consecutive
/// samples of a cosine set, turned into the tangent frame of a random vertex, lanes above
/// the horizon active, each walked from the root and down the tree's path to its origin (the
/// two walks must agree). Returns (lanes compared, lanes that differ, lanes blocked).
fn compare_fans_with_single_rays(inputs: &Surface, width: usize, packets: usize) -> [usize; 3] {
    let mut rng = Pcg32::new(11);
    let set = crate::sampling::cosine_hemisphere(1024, 3);
    let copies = dispatch::all_available();
    let mut counts = [0; 3];
    for _ in 0..packets {
        let (vertex, directions) = random_fan(inputs, &set, width, &mut rng);
        let normal = inputs.normals[vertex];
        let above = lane_mask(|l| l < width && normal.dot(directions[l]) > 0.0);
        let packet = FanPacket::new(inputs.origins[vertex], &directions, above);
        let expected = lane_mask(|l| {
            above & (1 << l) != 0
                && inputs
                    .bvh
                    .occluded(&Ray::new(inputs.origins[vertex], directions[l]), RAY_T_MAX)
        });
        let path = inputs.bvh.path_to(inputs.origins[vertex]);
        let both_walks = (&inputs.bvh, &[&PointPath::NONE, &path][..]);
        let checked = check_copies(&copies, both_walks, &packet, above, expected);
        counts.iter_mut().zip(checked).for_each(|(c, n)| *c += n);
    }
    counts
}

#[test]
fn fans_agree_with_single_rays_on_the_dragon_and_bunny() {
    for (name, widths) in [
        ("dragon_vrip_res3.ply.gz", &[LANES][..]),
        ("bunny.obj", &[1, 5, LANES - 1, LANES][..]),
    ] {
        let inputs = Surface::load(name);
        for &width in widths {
            let [lanes, differ, blocked] = compare_fans_with_single_rays(&inputs, width, 10_000);
            println!("{name}, {width} lanes: {lanes} lanes, {blocked} blocked, {differ} differ");
            assert!(
                blocked > lanes / 20,
                "too few blocked rays to test anything"
            );
            assert_eq!(differ, 0, "{name}, {width}-lane fans");
        }
    }
}

/// Every copy of the closest-hit fan traversal against single rays: fans of up to 16
/// consecutive samples of a cosine set from random vertices, some lanes inactive. The hits are
/// the single rays', triangle, distance and barycentrics bit for bit; 2CylinderEngine has
/// coincident faces, where the tie rule (`ray::replaces`) decides.
#[test]
fn fans_find_the_single_rays_closest_hits() {
    let set = crate::sampling::cosine_hemisphere(1024, 5);
    for name in [
        "dragon_vrip_res3.ply.gz",
        "bunny.obj",
        "gltf/2CylinderEngine.glb",
    ] {
        let inputs = Surface::load(name);
        let bvh = &inputs.bvh;
        let mut rng = Pcg32::new(13);
        let (mut hits, mut lanes) = (0, 0);
        for fan in 0..3_000 {
            let width = 1 + (rng.next_u32() as usize) % LANES;
            let (vertex, directions) = random_fan(&inputs, &set, width, &mut rng);
            let origin = inputs.origins[vertex];
            let skipped = rng.next_u32();
            let active = lane_mask(|l| l < width && (skipped >> l) & 7 != 0);
            let packet = FanPacket::new(origin, &directions, active);
            // Every other fan walks from the root, the rest down the path to their origin.
            let path = match fan % 2 {
                0 => bvh.path_to(origin),
                _ => PointPath::NONE,
            };
            for (copy_name, copy) in dispatch::all_available::<FanPacket, ClosestHits>() {
                let mut query = ClosestHits::new(RAY_T_MAX);
                copy(bvh, &packet, &path, &mut query);
                for (lane, &direction) in directions.iter().enumerate() {
                    let found = query.barycentrics(lane).map(|(u, v)| {
                        let tri = &bvh.triangles[query.triangle[lane] as usize];
                        let bits = [query.t[lane], u, v].map(f32::to_bits);
                        (tri.source_index, bits)
                    });
                    if active & (1 << lane) == 0 {
                        assert_eq!(found, None, "{copy_name}: an inactive lane hit");
                        continue;
                    }
                    let single = bvh
                        .closest_hit(&Ray::new(origin, direction), RAY_T_MAX)
                        .map(|(triangle, hit)| (triangle, [hit.t, hit.u, hit.v].map(f32::to_bits)));
                    assert_eq!(found, single, "{copy_name} {name}");
                    lanes += 1;
                    hits += single.is_some() as usize;
                }
            }
        }
        println!("{name}: {lanes} lanes, {hits} hit");
        assert!(hits > 1_000, "too few hits ({hits}) to test anything");
    }
}

#[test]
fn inactive_and_empty_lanes_never_report() {
    // Inside a closed box every ray is blocked: exactly the active lanes must come back.
    let (mesh, _) = prepare(builtin::closed_box(Vec3::splat(-1.0), Vec3::splat(1.0), 4)).unwrap();
    let bvh = crate::bvh::Bvh::build(&mesh.positions, &mesh.triangles);
    let points: Vec<Vec3> = (0..LANES)
        .map(|i| Vec3::new(i as f32 / LANES as f32 - 0.5, 0.1, -0.2))
        .collect();
    let mut rng = Pcg32::new(3);
    for width in [1, 7, LANES] {
        let origins = PacketOrigins::new(&points[..width]);
        for _ in 0..50 {
            let direction = random_direction(&mut rng);
            for active in [0, 0b1010_0110_0101_1001, ALL_LANES] {
                let packet = RayPacket::new(&origins, direction, active);
                let expected = active & origins.filled;
                assert_eq!(packet.active, expected);
                for (name, f) in dispatch::all_available() {
                    let blocked = any_hit(f, &bvh, &packet, &PointPath::NONE, RAY_T_MAX);
                    assert_eq!(blocked, expected, "{name}");
                }
            }
        }
    }
    // The same for fans from one point inside.
    for width in [1, 7, LANES] {
        let directions: Vec<Vec3> = (0..width).map(|_| random_direction(&mut rng)).collect();
        for active in [0, 0b1010_0110_0101_1001, ALL_LANES] {
            let packet = FanPacket::new(points[3], &directions, active);
            let expected = active & (ALL_LANES >> (LANES - width));
            assert_eq!(packet.active, expected);
            let path = bvh.path_to(points[3]);
            assert!(path.deepest().is_some(), "the box holds the point");
            for (name, f) in dispatch::all_available() {
                for path in [&path, &PointPath::NONE] {
                    let blocked = any_hit(f, &bvh, &packet, path, RAY_T_MAX);
                    assert_eq!(blocked, expected, "{name} fan");
                }
            }
        }
    }
}

#[test]
fn empty_scene_blocks_nothing() {
    let bvh = crate::bvh::Bvh::build(&[], &[]);
    let origins = PacketOrigins::new(&[Vec3::ZERO; 3]);
    let packet = RayPacket::new(&origins, Vec3::X, ALL_LANES);
    assert_eq!(occluded(&bvh, &packet, RAY_T_MAX), 0);
    let fan = FanPacket::new(Vec3::ZERO, &[Vec3::X, Vec3::Y], ALL_LANES);
    let path = bvh.path_to(Vec3::ZERO);
    assert_eq!(path.deepest(), None);
    assert_eq!(occluded_fan(&bvh, &fan, &path, RAY_T_MAX), 0);
}
