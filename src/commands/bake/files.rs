//! What a bake reads and writes: the mesh or scene loaded, the outputs checked before any
//! work, the preview rendered and written.

use super::*;

/// What `bake` bakes as `spec` asks: the mesh named on the command line (a glTF scene keeps its
/// document, to be written back with its transfer, unless its container is a mesh), or the
/// built-in scene (the interior, for local lights); and a name for messages.
pub(crate) fn load_bake_input(
    spec: &BakeSpec,
    mesh: &Option<PathBuf>,
) -> Result<(scene::Scene, Option<scene::gltf::GltfScene>, String)> {
    let name = bake_name(spec, mesh);
    match mesh {
        Some(path) if spec.container == Container::GltfInPlace => {
            let (gltf, loaded) = scene::gltf::load(path)?;
            for note in &gltf.notes {
                eprintln!("note: {note}");
            }
            Ok((loaded, Some(gltf), name))
        }
        Some(path) => Ok((load_mesh(path)?, None, name)),
        None if spec.local.is_some() => Ok((scene::builtin::interior_scene(), None, name)),
        None => Ok((scene::builtin::default_scene(), None, name)),
    }
}

/// Geometry errors come from preparation, which no longer knows the file: name it.
pub(crate) fn naming_the_mesh(error: Error, mesh: &str) -> Error {
    match error {
        Error::Geometry(_) => Error::mesh(mesh, error.to_string()),
        other => other,
    }
}

/// The preview's width and height in pixels.
const PREVIEW_SIZE: (u32, u32) = (640, 480);

/// A preview rendered, not yet written.
pub(super) struct Preview {
    pixels: Vec<[f32; 4]>,
    width: u32,
    height: u32,
}

impl Preview {
    fn write(&self, path: &Path) -> Result<()> {
        render::write_image(
            path,
            &self.pixels,
            self.width,
            self.height,
            ToneMap::Reinhard,
            0.0,
        )?;
        eprintln!("preview -> {}", path.display());
        Ok(())
    }
}

/// `baked` rendered under the default sky and sun.
pub(super) fn render_preview(context: &GpuContext, baked: &bake::BakedMesh) -> Result<Preview> {
    let (width, height) = PREVIEW_SIZE;
    let light = light::preview_light(baked.metadata.bands)?;
    let pixels = render::preview(context, baked, &light, None, width, height)?;
    Ok(Preview {
        pixels,
        width,
        height,
    })
}

/// A streamed bake's preview: `radiance` at the vertices of its prepared `scene`, drawn as
/// [`render_preview`] draws the whole bake.
pub(super) fn render_radiance_preview(
    context: &GpuContext,
    scene: &scene::Scene,
    radiance: &[[f32; 3]],
) -> Result<Preview> {
    let (width, height) = PREVIEW_SIZE;
    let camera = render::Camera::framing_scene(scene);
    let pixels = render::render(context, scene, radiance, &camera, width, height)?;
    Ok(Preview {
        pixels,
        width,
        height,
    })
}

/// Writes the preview; if it cannot be written, removes the bake just written (and its
/// lightmap), since a bake is whole or not at all.
pub(super) fn write_preview_or_undo(
    path: &Path,
    image: &Preview,
    output: &Path,
    lightmap: bool,
) -> Result<()> {
    let written = image.write(path);
    if written.is_err() {
        let _ = std::fs::remove_file(output);
        if lightmap {
            let _ = std::fs::remove_file(lightmap_beside(output));
        }
    }
    written
}

/// The name a bake of `mesh` as `spec` asks reports and names its default output by: the mesh
/// file's, or the built-in scene's.
pub(crate) fn bake_name(spec: &BakeSpec, mesh: &Option<PathBuf>) -> String {
    match mesh {
        Some(path) => stem(path),
        None if spec.local.is_some() => "interior".to_string(),
        None => "default-scene".to_string(),
    }
}

/// Where a bake of `mesh` goes without `-o`: `<its name>.prt.glb` in the current directory.
pub(super) fn default_output(spec: &BakeSpec, mesh: &Option<PathBuf>) -> PathBuf {
    PathBuf::from(format!("{}.prt.glb", bake_name(spec, mesh)))
}

/// The lightmap a bake to `glb` writes beside it.
pub(super) fn lightmap_beside(glb: &Path) -> PathBuf {
    glb.with_file_name(glb::lightmap_file_name(glb))
}

/// The files one bake writes — the .glb at `output`, the lightmap beside it (when `spec` has
/// one), the preview — checked before any work: their names end as their formats need, none is
/// the mesh, one of `inputs` (a merge's parts) or another of them, and their directories exist.
pub(crate) fn check_bake_outputs(
    spec: &BakeSpec,
    preview: Option<&Path>,
    mesh: &Option<PathBuf>,
    output: &Path,
    inputs: &[&Path],
) -> Result<()> {
    let glb_output = fs::Output {
        option: "-o",
        path: output,
    };
    let lightmap = lightmap_beside(output);
    let mut outputs = vec![glb_output];
    if spec.receivers.lightmap.is_some() {
        if fs::is_special_file(output) {
            return Err(Error::Options(format!(
                "--lightmap writes {} beside the .glb; -o {} is not a file to put it beside",
                glb::lightmap_file_name(output),
                output.display()
            )));
        }
        outputs.push(fs::Output {
            option: "-o",
            path: &lightmap,
        });
    }
    if let Some(preview) = preview {
        outputs.push(fs::Output {
            option: "--preview",
            path: preview,
        });
    }
    let mut all_inputs: Vec<&Path> = mesh.iter().map(PathBuf::as_path).collect();
    all_inputs.extend_from_slice(inputs);
    fs::check_outputs(&outputs, &all_inputs)?;
    fs::check_extension(glb_output, &["glb"], "a bake is written as binary glTF")?;
    fs::check_destination(output)?;
    if let Some(preview) = preview {
        check_preview(preview)?;
    }
    Ok(())
}

/// `--preview` names an image (.png or .exr) in a directory that exists.
pub(crate) fn check_preview(preview: &Path) -> Result<()> {
    render::check_image_output("--preview", preview)?;
    fs::check_destination(preview).map(|_| ())
}

/// The mesh named on the command line, or the built-in scene; and a name for messages.
pub(crate) fn load_scene(mesh: &Option<PathBuf>) -> Result<(scene::Scene, String)> {
    match mesh {
        Some(path) => Ok((load_mesh(path)?, stem(path))),
        None => Ok((scene::builtin::default_scene(), "default-scene".to_string())),
    }
}

/// A mesh file, saying what its reader repaired (one `warning:` line each).
pub(crate) fn load_mesh(path: &Path) -> Result<scene::Scene> {
    let (scene, warnings) = scene::load_with_warnings(path)?;
    for warning in warnings {
        eprintln!("warning: {}: {warning}", stem(path));
    }
    Ok(scene)
}

/// The name a mesh file is reported by.
pub(crate) fn stem(path: &Path) -> String {
    scene::batch::mesh_name(path)
}

pub(crate) fn mesh_shown(mesh: &Option<PathBuf>) -> String {
    mesh.as_ref()
        .map_or_else(|| "built-in scene".to_string(), |p| p.display().to_string())
}
