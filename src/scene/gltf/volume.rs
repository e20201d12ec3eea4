//! The scattering volumes a glTF scene's materials describe, as the file gives them:
//! `KHR_materials_volume` (attenuation colour and distance, world units; a thickness of zero
//! is a thin wall, no volume), `KHR_materials_volume_scatter` (the multi-scatter albedo and
//! the phase function's anisotropy) and `KHR_materials_ior`. A volume without the scatter
//! extension only absorbs (clear glass, tinted liquid): nothing in it scatters, so it has no
//! subsurface light to bake and is left opaque, with a note. What the numbers mean as a medium
//! is the bake's business (`bake::subsurface`).

use serde_json::{Map, Value};

use super::{material_label, GltfScene};

/// A material's scattering volume, its values as the file gives them (defaults filled in).
#[derive(Clone, Debug, PartialEq)]
pub struct MaterialVolume {
    /// The glTF material's index.
    pub material: usize,
    /// Its index and name, for the user.
    pub label: String,
    pub ior: f32,
    pub attenuation_color: [f32; 3],
    /// World units (metres); infinite where the file gives none.
    pub attenuation_distance: f32,
    pub multiscatter_color: [f32; 3],
    pub scatter_anisotropy: f32,
}

/// The scattering volumes of a scene and which vertices lie on each.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneVolumes {
    pub volumes: Vec<MaterialVolume>,
    /// Per vertex of the [`crate::scene::Scene`] `load` made: its index in `volumes`, or
    /// [`NO_VOLUME`].
    pub of_vertex: Vec<u32>,
    /// Materials with a volume that does not scatter, one line each.
    pub notes: Vec<String>,
}

/// A vertex on no scattering volume.
pub const NO_VOLUME: u32 = u32::MAX;

const VOLUME: &str = "KHR_materials_volume";
const SCATTER: &str = "KHR_materials_volume_scatter";
const IOR: &str = "KHR_materials_ior";

/// The scattering volumes of the materials `gltf`'s baked primitives use (`vertex_count` the
/// vertices `load` made of them); `None` where no baked primitive's material scatters.
pub fn scattering_volumes(gltf: &GltfScene, vertex_count: usize) -> Option<SceneVolumes> {
    let mut volumes: Vec<MaterialVolume> = Vec::new();
    let mut of_vertex = vec![NO_VOLUME; vertex_count];
    let mut clear = Vec::new();
    for instance in &gltf.instances {
        let mesh = &gltf.root.meshes[instance.mesh];
        for span in &instance.primitives {
            let Some(index) = mesh.primitives[span.primitive].material.map(|m| m.value()) else {
                continue;
            };
            let Some(material) = gltf.root.materials.get(index) else {
                continue;
            };
            let extensions = material
                .extensions
                .as_ref()
                .map(|e| &e.others)
                .cloned()
                .unwrap_or_default();
            let Some(volume) = extensions.get(VOLUME).and_then(Value::as_object) else {
                continue;
            };
            let label = material_label(&gltf.root, index);
            let thickness = number(volume, "thicknessFactor").unwrap_or(0.0);
            let Some(scatter) = extensions.get(SCATTER).and_then(Value::as_object) else {
                clear.push(format!("{label} (no {SCATTER}: it only absorbs)"));
                continue;
            };
            if thickness <= 0.0 {
                clear.push(format!(
                    "{label} (thicknessFactor 0: a thin wall, no volume)"
                ));
                continue;
            }
            let at = match volumes.iter().position(|v| v.material == index) {
                Some(at) => at,
                None => {
                    volumes.push(MaterialVolume {
                        material: index,
                        label,
                        ior: extensions
                            .get(IOR)
                            .and_then(Value::as_object)
                            .and_then(|ior| number(ior, "ior"))
                            .unwrap_or(1.5),
                        attenuation_color: color(volume, "attenuationColor").unwrap_or([1.0; 3]),
                        attenuation_distance: number(volume, "attenuationDistance")
                            .unwrap_or(f32::INFINITY),
                        multiscatter_color: color(scatter, "multiscatterColor").unwrap_or([0.0; 3]),
                        scatter_anisotropy: number(scatter, "scatterAnisotropy").unwrap_or(0.0),
                    });
                    volumes.len() - 1
                }
            };
            of_vertex[span.first..span.first + span.count].fill(at as u32);
        }
    }
    clear.sort();
    clear.dedup();
    let notes = clear
        .into_iter()
        .map(|why| format!("material {why} is baked opaque"))
        .collect();
    Some(SceneVolumes {
        volumes,
        of_vertex,
        notes,
    })
    .filter(|found| !found.volumes.is_empty() || !found.notes.is_empty())
}

fn number(object: &Map<String, Value>, key: &str) -> Option<f32> {
    object.get(key).and_then(Value::as_f64).map(|v| v as f32)
}

fn color(object: &Map<String, Value>, key: &str) -> Option<[f32; 3]> {
    let values = object.get(key)?.as_array()?;
    match values.as_slice() {
        [r, g, b] => Some([r, g, b].map(|c| c.as_f64().unwrap_or(f64::NAN) as f32)),
        _ => Some([f32::NAN; 3]),
    }
}
