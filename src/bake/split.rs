//! Meshes split where their lightmap coordinates differ: a lightmap gives each triangle corner
//! its own coordinates, and a glTF vertex holds one pair, so a vertex on a seam between charts
//! becomes one vertex per chart (`split_at_seams`, the baked file), or every corner its own
//! (`split_corners`, for a mesh read back or drawn).

use std::collections::HashMap;

use glam::Vec3;

use super::Transfer;
use crate::scene::Scene;

/// The scene with every triangle corner its own vertex (triangle t's corners become vertices
/// 3t, 3t + 1, 3t + 2), and the vertex transfer copied to them: the mesh a lightmap's
/// per-corner coordinates belong to.
pub fn split_corners(scene: &Scene, transfer: &Transfer) -> (Scene, Transfer) {
    let picked = corner_vertices(scene);
    (
        corner_scene(scene, &picked),
        picked_transfer(transfer, &picked),
    )
}

/// The scene of [`split_corners`], without transfer.
pub fn split_scene_corners(scene: &Scene) -> Scene {
    corner_scene(scene, &corner_vertices(scene))
}

/// Each triangle corner's vertex, corner i of triangle t at `3t + i`.
fn corner_vertices(scene: &Scene) -> Vec<u32> {
    scene.triangles.iter().flatten().copied().collect()
}

/// The scene whose vertices are the corners `picked` ([`corner_vertices`]), each triangle
/// over its own three.
fn corner_scene(scene: &Scene, picked: &[u32]) -> Scene {
    let triangles = (0..scene.triangles.len() as u32)
        .map(|t| [3 * t, 3 * t + 1, 3 * t + 2])
        .collect();
    picked_scene(scene, picked, triangles)
}

/// The scene split only where its lightmap's charts meet, and the vertex transfer copied to
/// the new vertices: a vertex becomes one vertex per distinct coordinate pair among its
/// corners (`corner_texcoords`, corner i of triangle t at `3t + i`), in the order of their
/// first corners. A chart's inside keeps its vertices shared, so the file holds a vertex per
/// vertex and seam copy, not one per corner.
pub fn split_at_seams(
    scene: &Scene,
    transfer: &Transfer,
    corner_texcoords: &[[f32; 2]],
) -> (Scene, Transfer) {
    let mut index_of: HashMap<(u32, [u32; 2]), u32> = HashMap::new();
    let mut picked = Vec::new();
    let corners = scene.triangles.iter().flatten().zip(corner_texcoords);
    let indices: Vec<u32> = corners
        .map(|(&v, uv)| {
            *index_of
                .entry((v, uv.map(f32::to_bits)))
                .or_insert_with(|| {
                    picked.push(v);
                    picked.len() as u32 - 1
                })
        })
        .collect();
    let triangles = indices
        .chunks_exact(3)
        .map(|c| [c[0], c[1], c[2]])
        .collect();
    (
        picked_scene(scene, &picked, triangles),
        picked_transfer(transfer, &picked),
    )
}

/// The scene whose vertex i is `scene`'s vertex `picked[i]`, with `triangles` over them.
fn picked_scene(scene: &Scene, picked: &[u32], triangles: Vec<[u32; 3]>) -> Scene {
    let pick = |values: &[Vec3]| {
        picked
            .iter()
            .map(|&i| values[i as usize])
            .collect::<Vec<_>>()
    };
    Scene {
        positions: pick(&scene.positions),
        normals: scene.normals.as_deref().map(pick),
        albedo: pick(&scene.albedo),
        triangles,
    }
}

/// The transfer whose vertex i is `transfer`'s vertex `picked[i]`.
fn picked_transfer(transfer: &Transfer, picked: &[u32]) -> Transfer {
    let stride = transfer.channels() as usize * transfer.coeffs_per_channel();
    let coeffs: Vec<f32> = picked
        .iter()
        .flat_map(|&i| {
            let i = i as usize;
            transfer.coeffs()[i * stride..(i + 1) * stride]
                .iter()
                .copied()
        })
        .collect();
    let (bands, channels) = (transfer.bands(), transfer.channels());
    Transfer::new(bands, channels, picked.len(), coeffs)
        .expect("a copy of a vertex's coefficients for every vertex picked")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bake::TexelBake;
    use crate::receivers::atlas::{generate_atlas, Atlas};
    use crate::scene::builtin;
    use crate::scene::prepare::prepare;

    /// The atlas' corners as lightmap coordinates, corner i of triangle t at `3t + i`.
    fn corner_texcoords(atlas: &Atlas) -> Vec<[f32; 2]> {
        let size = glam::Vec2::new(atlas.width as f32, atlas.height as f32);
        atlas
            .corners
            .iter()
            .flatten()
            .map(|&c| (c / size).to_array())
            .collect()
    }

    #[test]
    fn a_mesh_is_split_only_where_its_charts_meet() {
        let (sphere, _) = prepare(builtin::icosphere(Vec3::ZERO, 1.0, 2)).unwrap();
        let flat = builtin::grid_plane(Vec3::ZERO, Vec3::X, Vec3::NEG_Z, 6, Vec3::ONE);
        let (flat, _) = prepare(flat).unwrap();
        for (scene, one_chart) in [(sphere, false), (flat, true)] {
            let v = scene.vertex_count();
            let values = (0..v).map(|i| i as f32).collect();
            let transfer = Transfer::new(1, 1, v, values).expect("a value for each vertex");
            let texcoords = corner_texcoords(&generate_atlas(&scene, 16.0).unwrap());
            let (split, split_transfer) = split_at_seams(&scene, &transfer, &texcoords);
            let texels = TexelBake {
                width: 1,
                height: 1,
                texcoords: texcoords.clone(),
                set: 0,
                transfer: Transfer::zeros(1, 1, 1),
                held: None,
            };
            let per_vertex = texels.vertex_texcoords(&split).expect("corners agree");
            // Every corner keeps its vertex's position and transfer, and its coordinates.
            assert_eq!(split.triangles.len(), scene.triangles.len());
            let corners = scene
                .triangles
                .iter()
                .flatten()
                .zip(split.triangles.iter().flatten());
            let mut copies: HashMap<u32, Vec<u32>> = HashMap::new();
            for ((&old, &new), uv) in corners.zip(&texcoords) {
                assert_eq!(split.positions[new as usize], scene.positions[old as usize]);
                assert_eq!(split_transfer.coeffs()[new as usize], old as f32);
                assert_eq!(per_vertex[new as usize], *uv);
                let list = copies.entry(old).or_default();
                if !list.contains(&new) {
                    list.push(new);
                }
            }
            // A vertex is copied once per chart it lies on, no more.
            let copies_needed = |old: u32| {
                let mut seen: Vec<[u32; 2]> = scene
                    .triangles
                    .iter()
                    .flatten()
                    .zip(&texcoords)
                    .filter(|(&o, _)| o == old)
                    .map(|(_, uv)| uv.map(f32::to_bits))
                    .collect();
                seen.sort_unstable();
                seen.dedup();
                seen.len()
            };
            for (&old, list) in &copies {
                assert_eq!(list.len(), copies_needed(old));
            }
            assert_eq!(
                split.vertex_count() == v,
                one_chart,
                "{} of {v}",
                split.vertex_count()
            );
            assert!(split.vertex_count() < 3 * scene.triangles.len());
        }
    }

    #[test]
    fn split_corners_keep_every_triangle_and_its_values() {
        let (scene, _) = prepare(builtin::icosphere(Vec3::ZERO, 1.0, 1)).unwrap();
        let transfer = Transfer::new(
            1,
            1,
            scene.vertex_count(),
            (0..scene.vertex_count()).map(|v| v as f32).collect(),
        )
        .expect("a value for each vertex");
        let (split, split_transfer) = split_corners(&scene, &transfer);
        assert_eq!(split.vertex_count(), 3 * scene.triangle_count());
        for (t, corners) in scene.triangles.iter().enumerate() {
            for (i, &v) in corners.iter().enumerate() {
                let s = split.triangles[t][i] as usize;
                assert_eq!(split.positions[s], scene.positions[v as usize]);
                assert_eq!(split_transfer.coeffs()[s], v as f32);
            }
        }
    }
}
