//! A primitive's per-vertex albedo from its material: `baseColorFactor × baseColorTexture ×
//! COLOR_0` (glTF 2.0 §3.9.2), the texture averaged over the surface around each vertex
//! ([`crate::scene::texture::vertex_averages`]) rather than point-sampled at its UV.

use std::collections::HashMap;

use glam::Vec3;
use gltf_json::material::AlphaMode;
use gltf_json::mesh::{Primitive, Semantic};
use gltf_json::validation::Checked;

use super::accessor::dense;
use super::{GltfScene, Notes, Part};
use crate::scene::texture::{vertex_averages, Texture, UvTransform, Wrap};

/// Decoded base colour textures by glTF texture index: a texture shared by many primitives
/// is decoded once.
#[derive(Default)]
pub(super) struct Textures(HashMap<usize, Texture>);

/// `part` with its albedo set from the primitive's material and colours.
pub(super) fn apply(
    gltf: &GltfScene,
    primitive: &Primitive,
    mut part: Part,
    textures: &mut Textures,
    what: &str,
    notes: &mut Notes,
) -> std::result::Result<Part, String> {
    let root = &gltf.root;
    let material = match primitive.material {
        Some(index) => Some((
            index.value(),
            root.materials
                .get(index.value())
                .ok_or_else(|| format!("{what} uses a missing material"))?,
        )),
        None => None,
    };
    let mut factor = [1.0f32; 3];
    if let Some((index, material)) = material {
        if matches!(
            material.alpha_mode,
            Checked::Valid(AlphaMode::Mask | AlphaMode::Blend)
        ) {
            notes.see_through.push(index);
        }
        let [r, g, b, _] = material.pbr_metallic_roughness.base_color_factor.0;
        factor = [r, g, b];
        if let Some(info) = &material.pbr_metallic_roughness.base_color_texture {
            let averaged = texture_averages(gltf, primitive, &part, info, textures, what)?;
            for (albedo, texel) in part.albedo.iter_mut().zip(averaged) {
                *albedo *= Vec3::new(texel[0], texel[1], texel[2]);
            }
        }
    }
    if let Some(colors) = primitive
        .attributes
        .get(&Checked::Valid(Semantic::Colors(0)))
    {
        let colors = dense(root, &gltf.buffers, colors.value())?;
        let components = colors.components;
        if !(components == 3 || components == 4) {
            return Err(format!("{what} COLOR_0 has {components} components"));
        }
        let values = colors.floats();
        for (albedo, color) in part.albedo.iter_mut().zip(values.chunks_exact(components)) {
            *albedo *= Vec3::new(color[0], color[1], color[2]);
        }
    }
    let factor = Vec3::from_array(factor);
    for albedo in &mut part.albedo {
        *albedo = (*albedo * factor).clamp(Vec3::ZERO, Vec3::ONE);
    }
    Ok(part)
}

/// The base colour texture averaged around each vertex of `part`.
fn texture_averages(
    gltf: &GltfScene,
    primitive: &Primitive,
    part: &Part,
    info: &gltf_json::texture::Info,
    textures: &mut Textures,
    what: &str,
) -> std::result::Result<Vec<[f32; 4]>, String> {
    let root = &gltf.root;
    let transform_extension = info
        .extensions
        .as_ref()
        .and_then(|e| e.texture_transform.as_ref());
    let transform = transform_extension.map_or_else(UvTransform::default, |t| UvTransform {
        offset: t.offset.0,
        rotation: t.rotation.0,
        scale: t.scale.0,
    });
    let set = transform_extension
        .and_then(|t| t.tex_coord)
        .unwrap_or(info.tex_coord);
    let uvs = match primitive
        .attributes
        .get(&Checked::Valid(Semantic::TexCoords(set)))
    {
        Some(accessor) => dense(root, &gltf.buffers, accessor.value())?
            .vectors::<2>(&format!("{what} TEXCOORD_{set}"))?,
        None => {
            return Err(format!(
                "{what}: its base colour texture uses TEXCOORD_{set}, which it lacks"
            ))
        }
    };
    // A NaN or infinite UV would sample nothing and leave the albedo, and so the transfer,
    // silently wrong: refused like a non-finite position.
    if let Some(vertex) = uvs.iter().position(|uv| !uv.iter().all(|c| c.is_finite())) {
        return Err(format!(
            "{what} TEXCOORD_{set} is NaN or infinite at vertex {vertex} ({}, {}), so its base \
             colour texture cannot be sampled there",
            uvs[vertex][0], uvs[vertex][1]
        ));
    }
    let texture = match textures.0.entry(info.index.value()) {
        std::collections::hash_map::Entry::Occupied(known) => known.into_mut(),
        std::collections::hash_map::Entry::Vacant(slot) => {
            slot.insert(decode(gltf, info.index.value())?)
        }
    };
    Ok(vertex_averages(
        &part.positions,
        &uvs,
        &part.triangles,
        texture,
        &transform,
    ))
}

/// glTF texture `index`: its image decoded (sRGB to linear) with its sampler's wrap modes.
fn decode(gltf: &GltfScene, index: usize) -> std::result::Result<Texture, String> {
    let root = &gltf.root;
    let texture = root
        .textures
        .get(index)
        .ok_or_else(|| format!("texture {index} does not exist"))?;
    let image_index = texture.source.value();
    let image = gltf
        .images
        .get(image_index)
        .ok_or_else(|| format!("texture {index} uses a missing image"))?;
    let what = format!("image {image_index}");
    let decoded = Texture::decode(&image.bytes, &what).map_err(|e| e.to_string())?;
    let (wrap_s, wrap_t) = match texture.sampler.and_then(|s| root.samplers.get(s.value())) {
        Some(sampler) => (wrap(&sampler.wrap_s), wrap(&sampler.wrap_t)),
        None => (Wrap::Repeat, Wrap::Repeat),
    };
    Ok(decoded.with_wrap(wrap_s, wrap_t))
}

fn wrap(mode: &Checked<gltf_json::texture::WrappingMode>) -> Wrap {
    match mode {
        Checked::Valid(mode) => Wrap::from_gl(mode.as_gl_enum()).unwrap_or_default(),
        Checked::Invalid => Wrap::default(),
    }
}
