//! Tests of `local`.

use super::*;
use crate::scene::builtin;

#[test]
fn frames_are_numbered_only_when_there_are_several() {
    let path = std::path::Path::new("out/seq.png");
    assert_eq!(frame_path(path, 0, 1), path);
    assert_eq!(
        frame_path(path, 7, 30),
        std::path::Path::new("out/seq_007.png")
    );
}

#[test]
fn the_interior_is_closed_and_free_space_is_told_from_inside_objects() {
    let (scene, _) = prepare(builtin::interior_scene()).unwrap();
    let bvh = Bvh::build(&scene.positions, &scene.triangles);
    let normals = scene.normals.as_deref().unwrap();
    // No ray from the middle of either room leaves the scene.
    let mut rng = Pcg32::new(4);
    for room in [Vec3::new(-2.0, 1.2, 1.0), Vec3::new(1.6, 1.2, 1.0)] {
        assert!(in_free_space(&scene, normals, &bvh, room));
        for _ in 0..2000 {
            let d = Vec3::new(
                rng.next_f32() - 0.5,
                rng.next_f32() - 0.5,
                rng.next_f32() - 0.5,
            );
            let ray = Ray::new(room, d.normalize());
            assert!(bvh.closest_hit(&ray, RAY_T_MAX).is_some(), "{room} {d}");
        }
    }
    // Inside the table top, the wall and the ball.
    for inside in [
        Vec3::new(-2.0, 0.75, 0.0),
        Vec3::new(0.125, 1.0, -1.0),
        Vec3::new(-0.875, 0.375, -1.25),
    ] {
        assert!(!in_free_space(&scene, normals, &bvh, inside), "{inside}");
    }
    assert_eq!(crate::scene::extent_of(&scene.positions), bvh.extent());
}

#[test]
fn depth_clusters_within_the_maps_are_the_most_that_take_no_more_bytes() {
    for (receivers, cells, components) in [(1839, 256, 24), (13118, 256, 24), (529, 64, 8)] {
        let maps = 4 * receivers * cells;
        let stored = |clusters: u32| {
            stored_bytes(
                (clusters as usize, components),
                cells,
                receivers,
                Precision::F32,
            )
        };
        let most = depth_clusters_within_maps(receivers, cells, components).unwrap();
        assert!(stored(most) <= maps && stored(most + 1) > maps);
    }
    // The bunny's 1,839 receivers at the defaults (16 x 16 directions, 24 components): 66
    // clusters, not the default 128, whose bases alone take 3.3 MB of its 1.9 MB of maps.
    assert_eq!(depth_clusters_within_maps(1839, 256, 24), Some(66));
    // More components than directions: no cluster pays.
    assert_eq!(depth_clusters_within_maps(100, 16, 16), None);
}
