//! `prt-gpu view` and `prt-gpu export x3d`: the run-time half, for a browser.

use std::path::{Path, PathBuf};

use clap::Subcommand;
use glam::Vec3;

use super::args::{parse_finite, LightShaping};
use super::light::{load_light, say_warnings, shape};
use prt_gpu::light::{self, EnvImage, Mapping, ShLight};
use prt_gpu::render::{Camera, ToneMap};
use prt_gpu::{fs, glb, view, x3d, Result};

#[derive(Subcommand)]
pub(crate) enum ExportCommand {
    /// An X3D scene (XML): the transfer as per-vertex FloatVertexAttribute nodes and a
    /// ComposedShader that dots them with the light, a field of the shader.
    X3d(X3dArgs),
}

#[derive(clap::Args)]
pub(crate) struct X3dArgs {
    /// A baked .glb (per vertex).
    baked: PathBuf,
    /// The light: light.json (at least the file's bands), or an environment map projected at
    /// the file's bands. Default: the preview's sky and sun.
    #[arg(long)]
    light: Option<PathBuf>,
    /// Environment-map parameterization (with --light ENVMAP).
    #[arg(long, value_enum)]
    mapping: Option<Mapping>,
    #[command(flatten)]
    shaping: LightShaping,
    /// The viewpoint: eye x,y,z, target x,y,z [, field of view in degrees]. Default: render's
    /// framing.
    #[arg(long, allow_hyphen_values = true)]
    camera: Option<Camera>,
    /// Exposure in stops, a field of the shader.
    #[arg(long, default_value_t = 0.0, value_parser = parse_finite, allow_hyphen_values = true)]
    exposure: f32,
    /// Tone mapping in the shader.
    #[arg(long, value_enum, default_value_t = ToneMap::Reinhard)]
    tone_map: ToneMap,
    /// Output scene.
    #[arg(short, long, default_value = "scene.x3d")]
    output: PathBuf,
}

#[derive(clap::Args)]
pub(crate) struct ViewArgs {
    /// Baked .glb files (per vertex); the page switches between them.
    #[arg(required = true)]
    baked: Vec<PathBuf>,
    /// The light: light.json (at least as many bands as every file), or an environment map
    /// projected at the most bands of the files. Default: the preview's sky and sun.
    #[arg(long)]
    light: Option<PathBuf>,
    /// Environment-map parameterization (with --light ENVMAP).
    #[arg(long, value_enum)]
    mapping: Option<Mapping>,
    /// Windowing and a starting rotation of the light (the page turns it further).
    #[command(flatten)]
    shaping: LightShaping,
    /// Output page.
    #[arg(short, long, default_value = "viewer.html")]
    output: PathBuf,
}

pub(crate) fn run_view(args: ViewArgs) -> Result<()> {
    check_page_output(
        &args.output,
        &args.baked,
        args.light.as_deref(),
        &["html", "htm"],
        "the viewer is written as one HTML page",
    )?;
    let mut bakes = Vec::new();
    for path in &args.baked {
        let read = glb::read_back(path)?;
        let extras = (read.probes, read.zonal);
        bakes.push((path.display().to_string(), read.baked, extras));
    }
    let bands = bakes
        .iter()
        .map(|(_, b, _)| b.metadata.bands)
        .max()
        .unwrap_or(1);
    let (light, map) = view_light(&args, bands)?;
    let rotation = args.shaping.rotate.unwrap_or(Vec3::ZERO);
    let sky = map.as_ref().map(|(image, mapping)| view::ViewerSky {
        image,
        mapping: *mapping,
        yaw_pitch_roll: [rotation.x as f64, rotation.y as f64, rotation.z as f64],
    });
    let inputs: Vec<view::ViewerBake> = bakes
        .iter()
        .map(|(name, baked, (probes, zonal))| view::ViewerBake {
            name: stem_name(name),
            baked,
            probes: probes.as_ref(),
            zonal: zonal.as_ref(),
        })
        .collect();
    view::write_viewer(&args.output, &inputs, &light, sky.as_ref())?;
    let size = std::fs::metadata(&args.output)
        .map(|m| m.len())
        .unwrap_or(0);
    let with_probes = inputs.iter().filter(|b| b.probes.is_some()).count();
    println!(
        "viewer of {} file(s){}, light of {} bands{}, {:.1} MB -> {}",
        inputs.len(),
        match with_probes {
            0 => String::new(),
            n => format!(" ({n} with probes: a sphere lit by them)"),
        },
        light.bands,
        if sky.is_some() {
            ", the map as the sky"
        } else {
            ""
        },
        size as f64 / 1e6,
        args.output.display()
    );
    Ok(())
}

/// The viewer's light, shaped, and the environment map it was projected from (if it was).
fn view_light(args: &ViewArgs, bands: u32) -> Result<(ShLight, Option<(EnvImage, Mapping)>)> {
    let (light, map) = match &args.light {
        Some(light_path) => {
            let (loaded, image) = light::load_with_image(light_path, bands, args.mapping, false)?;
            say_warnings(&loaded.warnings);
            (loaded.light, image.zip(loaded.mapping))
        }
        None => (light::preview_light(bands)?, None),
    };
    Ok((shape(light, &args.shaping), map))
}

pub(crate) fn run_export_x3d(args: X3dArgs) -> Result<()> {
    check_page_output(
        &args.output,
        std::slice::from_ref(&args.baked),
        args.light.as_deref(),
        &["x3d"],
        "the scene is written as X3D (XML encoding)",
    )?;
    let baked = glb::read_glb(&args.baked)?;
    let bands = baked.metadata.bands;
    let light = match &args.light {
        Some(light_path) => load_light(light_path, bands, args.mapping, false)?.light,
        None => light::preview_light(bands)?,
    };
    let light = shape(light, &args.shaping);
    let options = x3d::X3dOptions {
        camera: args
            .camera
            .unwrap_or_else(|| Camera::framing_scene(&baked.scene)),
        exposure_stops: args.exposure,
        tone_map: args.tone_map,
    };
    x3d::write_x3d(&args.output, &baked, &light, &options)?;
    println!(
        "exported {} vertices, {} bands x {} channel(s) in {} vertex attributes -> {}",
        baked.scene.vertex_count(),
        bands,
        baked.transfer.channels(),
        x3d::transfer_attributes(&baked),
        args.output.display()
    );
    Ok(())
}

/// `-o` of `view` and `export`, checked before any work: not one of the baked files or the
/// light, ending in one of `extensions`, in a directory that exists.
fn check_page_output(
    output: &Path,
    baked: &[PathBuf],
    light: Option<&Path>,
    extensions: &[&str],
    what: &str,
) -> Result<()> {
    let page = fs::Output {
        option: "-o",
        path: output,
    };
    let inputs: Vec<&Path> = baked.iter().map(PathBuf::as_path).chain(light).collect();
    fs::check_output(page, &inputs, extensions, what)
}

/// The file name the page lists a bake by.
fn stem_name(path: &str) -> String {
    Path::new(path)
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| path.to_string())
}
