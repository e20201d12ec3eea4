//! `prt-gpu render`: baked files relit and rasterised, under distant or local lights.

use std::path::{Path, PathBuf};

use glam::Vec3;

use super::args::{parse_finite, parse_point, parse_sphere, LightShaping};
use super::bake::open_render_device;
use super::light::{load_light, shape};
use prt_gpu::bake::gpu::GpuBaker;
use prt_gpu::device::DeviceChoice;
use prt_gpu::light::{self, Mapping};
use prt_gpu::local::lights::{self as local_lights, LocalLight};
use prt_gpu::local::{self, OperatorForm, Shadows};
use prt_gpu::render::{self, Camera, ToneMap};
use prt_gpu::zonal::Bend;
use prt_gpu::{fs, glb, Error, Result};

#[derive(clap::Args)]
pub(crate) struct RenderArgs {
    /// Baked .glb files; several are rendered side by side, left to right.
    #[arg(required = true)]
    pub(crate) baked: Vec<PathBuf>,
    /// The light: light.json, or an environment map projected at each file's bands.
    #[arg(long)]
    pub(crate) light: Option<PathBuf>,
    /// Environment-map parameterization (with --light ENVMAP).
    #[arg(long, value_enum)]
    pub(crate) mapping: Option<Mapping>,
    #[command(flatten)]
    pub(crate) shaping: LightShaping,
    /// Camera: eye x,y,z, target x,y,z [, vertical field of view in degrees]. Default: a
    /// three-quarter view that frames the mesh.
    #[arg(long, allow_hyphen_values = true)]
    pub(crate) camera: Option<Camera>,
    /// Draw the light behind the model as a sky dome (the SH light the model is lit by, so
    /// as smooth as its band count); without it the background is transparent black.
    #[arg(long)]
    pub(crate) sky: bool,
    /// Exposure in stops (PNG only).
    #[arg(long, default_value_t = 0.0, value_parser = parse_finite, allow_hyphen_values = true)]
    pub(crate) exposure: f32,
    /// Tone mapping for PNG; EXR keeps linear radiance.
    #[arg(long, value_enum, default_value_t = ToneMap::Reinhard)]
    pub(crate) tone_map: ToneMap,
    /// Size of each panel in pixels.
    #[arg(long, default_value_t = 640)]
    pub(crate) width: u32,
    #[arg(long, default_value_t = 480)]
    pub(crate) height: u32,
    /// Use the adapter whose name contains this text.
    #[arg(long)]
    pub(crate) adapter: Option<String>,
    /// Local-lights bakes: a point light at X,Y,Z of radiant intensity I (W/sr, default 1;
    /// irradiance I cos(theta) / r^2). Repeatable.
    #[arg(long, value_name = "X,Y,Z[,I]", allow_hyphen_values = true)]
    pub(crate) point_light: Vec<String>,
    /// Local-lights bakes: a spot light at X,Y,Z opening towards DX,DY,DZ with a hard cone of
    /// half angle A degrees, intensity I inside it (default 1). Repeatable.
    #[arg(long, value_name = "X,Y,Z,DX,DY,DZ,A[,I]", allow_hyphen_values = true)]
    pub(crate) spot_light: Vec<String>,
    /// Local-lights bakes: render N frames with the lights carried once round a circle about
    /// the vertical axis through the scene's centre (images OUTPUT_000.png, ...), and report
    /// the per-frame relighting time of each operator on the CPU and on the GPU (--device).
    #[arg(long, value_name = "N")]
    pub(crate) frames: Option<u32>,
    /// Local-lights bakes: where the relighting runs besides the CPU. `gpu`: both operators on
    /// any adapter (lavapipe included), an error without one; `cpu`: the CPU only; `auto`: a
    /// hardware GPU too where there is one.
    #[arg(long, value_enum, default_value_t = DeviceChoice::Auto)]
    pub(crate) device: DeviceChoice,
    /// With --frames: the circle's axis passes through X,Y,Z instead of the scene's centre.
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_point, allow_hyphen_values = true)]
    pub(crate) orbit: Option<Vec3>,
    /// Local-lights bakes: the direct-to-indirect operator the images use.
    #[arg(long, value_enum, default_value_t = OperatorForm::Compressed)]
    pub(crate) operator: OperatorForm,
    /// Local-lights bakes: how the direct light finds its shadows. `rays`: a shadow ray per
    /// vertex and light (exact); `depth-maps`: the bake's compressed depth maps (no ray
    /// tracing, shadow edges blurred over a map cell). Default: rays.
    #[arg(long, value_enum, value_name = "rays|depth-maps")]
    pub(crate) shadows: Option<Shadows>,
    /// Bakes with probes (bake --probes): a diffuse test sphere at X,Y,Z of radius R (default
    /// 5% of the scene's extent), lit by the probes at its centre as a moving object would be
    /// (trilinear on the grid). Repeatable.
    #[arg(long, value_name = "X,Y,Z[,R]", value_parser = parse_sphere, allow_hyphen_values = true)]
    pub(crate) probe_sphere: Vec<(Vec3, Option<f32>)>,
    /// Bakes with zonal transfer (bake --zonal): relight from it, each vertex's lobe about its
    /// stored axis (the rest pose), as an LDPRT runtime does, instead of from the SH transfer.
    #[arg(long)]
    pub(crate) zonal: bool,
    /// Bend the mesh along its height (+Y) by DEG at its top, as a deforming mesh would
    /// (`zonal::Bend`): with --zonal, each vertex's lobe turns with the surface there (LDPRT);
    /// without, the SH transfer is drawn as baked, as static PRT would show it.
    #[arg(long, value_name = "DEG", value_parser = parse_bend, allow_hyphen_values = true)]
    pub(crate) bend: Option<f32>,
    /// Output: an image, .png (tone-mapped sRGB) or .exr (linear HDR); or .glb: a copy of the
    /// (one) baked file with each vertex's relit radiance as its COLOR_0.
    #[arg(short, long, default_value = "preview.png")]
    pub(crate) output: PathBuf,
}

pub(crate) fn run_render(args: RenderArgs) -> Result<()> {
    check_render_outputs(&args)?;
    if let [only] = &args.baked[..] {
        if glb::local::is_local_file(&std::fs::read(only).map_err(|e| Error::io(only, e))?) {
            return run_local_render(&args, only);
        }
    }
    let local_only = !args.point_light.is_empty()
        || !args.spot_light.is_empty()
        || args.frames.is_some()
        || args.orbit.is_some()
        || args.shadows.is_some()
        || args.device != DeviceChoice::Auto;
    if local_only {
        return Err(Error::Options(
            "--point-light, --spot-light, --frames, --orbit, --shadows and --device relight one \
             local-lights bake (bake --mode local); a distant-light render rasterizes on \
             --adapter"
                .into(),
        ));
    }
    if is_glb(&args.output) {
        return write_relit_distant(&args);
    }
    let context = open_render_device(args.adapter.as_deref())?;
    let mut panels = Vec::new();
    for (panel_index, path) in args.baked.iter().enumerate() {
        let read = glb::read_back(path)?;
        let (baked, cpca) = (&read.baked, read.cpca.as_ref());
        let bands = baked.metadata.bands;
        let light = match &args.light {
            // Read again for each panel's bands; what it says, said once.
            Some(light_path) if panel_index == 0 => {
                load_light(light_path, bands, args.mapping, false)?.light
            }
            Some(light_path) => light::load(light_path, bands, args.mapping, false)?.light,
            None => light::preview_light(bands)?,
        };
        let light = shape(light, &args.shaping);
        let bend = args
            .bend
            .map(|degrees| Bend::of_bounds(baked.scene.bounds(), degrees));
        let drawn = bent(&baked.scene, bend);
        let camera = args.camera.unwrap_or_else(|| Camera::framing_scene(&drawn));
        let relit_on_cpu = args.zonal || cpca.is_some() || !args.probe_sphere.is_empty();
        let mut panel = match &cpca {
            // Relit on the CPU as a run-time would, then drawn; else the preview's own way
            // (which draws a lightmap by its texels).
            _ if relit_on_cpu || bend.is_some() => {
                let how = (cpca, args.zonal, bend);
                let radiance = vertex_radiance((path, &read), how, &light)?;
                let (scene, radiance) = match &args.probe_sphere[..] {
                    [] => (drawn, radiance),
                    spheres => with_probe_spheres((path, &read), radiance, &light, spheres)?,
                };
                render::render(
                    &context,
                    &scene,
                    &radiance,
                    &camera,
                    args.width,
                    args.height,
                )?
            }
            _ => render::preview(
                &context,
                baked,
                &light,
                Some(&camera),
                args.width,
                args.height,
            )?,
        };
        if args.sky {
            render::draw_sky(&mut panel, args.width, args.height, &camera, &light);
        }
        panels.push(panel);
    }
    let image = render::side_by_side(&panels, args.width, args.height)?;
    let width = args.width * panels.len() as u32;
    render::write_image(
        &args.output,
        &image,
        width,
        args.height,
        args.tone_map,
        args.exposure,
    )?;
    println!(
        "rendered {} panel(s) of {}x{} on {} -> {}",
        panels.len(),
        args.width,
        args.height,
        context.adapter.label(),
        args.output.display()
    );
    Ok(())
}

/// `--bend DEG`: a finite angle of at most a whole turn either way.
fn parse_bend(text: &str) -> std::result::Result<f32, String> {
    match text.parse::<f32>() {
        Ok(degrees) if degrees.is_finite() && degrees.abs() <= 360.0 => Ok(degrees),
        _ => Err(format!(
            "\"{text}\" is not an angle from -360 to 360 degrees"
        )),
    }
}

/// `scene` bent by `bend`, where there is one.
fn bent(scene: &prt_gpu::scene::Scene, bend: Option<Bend>) -> prt_gpu::scene::Scene {
    let mut drawn = scene.clone();
    if let Some(bend) = bend {
        drawn
            .positions
            .iter_mut()
            .for_each(|p| *p = bend.place(*p).0);
    }
    drawn
}

/// The exit radiance at the vertices of the bake `read` from `path` under `light`, albedo
/// applied: from its zonal transfer where `zonal` asks (as an LDPRT run-time relights), each
/// axis turned by `bend` at its vertex; from its clusters where it is compressed (the light
/// dotted into each cluster once, then per vertex); else from its SH transfer.
fn vertex_radiance(
    (path, read): (&Path, &glb::ReadBack),
    (cpca, zonal, bend): (Option<&prt_gpu::compress::Cpca>, bool, Option<Bend>),
    light: &light::ShLight,
) -> Result<Vec<[f32; 3]>> {
    let baked = &read.baked;
    if zonal {
        let zonal = read.zonal.as_ref().ok_or_else(|| {
            Error::Options(format!(
                "--zonal: {} holds no zonal transfer (bake it with --zonal BANDS)",
                path.display()
            ))
        })?;
        let axes: Vec<Vec3> = match bend {
            Some(bend) => (zonal.axes().iter().zip(&baked.scene.positions))
                .map(|(axis, &p)| bend.place(p).1 * *axis)
                .collect(),
            None => zonal.axes().to_vec(),
        };
        return Ok(render::apply_albedo(baked, zonal.relight(&axes, light)?));
    }
    match cpca {
        Some(cpca) => Ok(render::apply_albedo(baked, cpca.relight(light)?)),
        None => render::relight_baked(baked, light),
    }
}

/// `radiance` of the baked scene's vertices with `spheres` added, lit by the probes of the
/// bake `read` from `path`.
fn with_probe_spheres(
    (path, read): (&Path, &glb::ReadBack),
    radiance: Vec<[f32; 3]>,
    light: &light::ShLight,
    spheres: &[(Vec3, Option<f32>)],
) -> Result<(prt_gpu::scene::Scene, Vec<[f32; 3]>)> {
    let baked = &read.baked;
    let probes = read.probes.as_ref().ok_or_else(|| {
        Error::Options(format!(
            "--probe-sphere: {} holds no probes (bake it with --probes or --probe-points)",
            path.display()
        ))
    })?;
    let default_radius = render::default_sphere_radius(&baked.scene);
    let spheres: Vec<render::ProbeSphere> = spheres
        .iter()
        .map(|&(centre, radius)| render::ProbeSphere {
            centre,
            radius: radius.unwrap_or(default_radius),
        })
        .collect();
    render::with_probe_spheres(&baked.scene, radiance, probes, &spheres, light)
}

/// `render FILE --light ... -o relit.glb`: the file's relit radiance as COLOR_0 of a copy.
fn write_relit_distant(args: &RenderArgs) -> Result<()> {
    let [path] = &args.baked[..] else {
        return Err(Error::Options(
            "-o .glb writes the relit radiance of one baked file; give one".into(),
        ));
    };
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    if glb::is_scene_file(&bytes) {
        return write_relit_scene(args, path);
    }
    let read = glb::read_back(path)?;
    let (baked, cpca) = (&read.baked, read.cpca.as_ref());
    let (light, name) = relit_light(args, baked.metadata.bands)?;
    let radiance = vertex_radiance((path, &read), (cpca, args.zonal, None), &light)?;
    let lightmap = match &baked.lightmap {
        Some(texels) => {
            let relit = render::relight(&texels.transfer, &light)?;
            Some(write_relit_lightmap(&args.output, texels, relit)?)
        }
        None => None,
    };
    let described = lightmap.as_ref().map(|(lightmap, _)| lightmap);
    let scale = glb::relit::write_relit_copy(path, &args.output, &radiance, (&name, described))
        .inspect_err(|_| remove_relit_lightmap(&lightmap))?;
    println!(
        "relit {} vertices under {name} -> {} ({}){}",
        radiance.len(),
        args.output.display(),
        relit_attributes(scale),
        relit_lightmap_line(&lightmap)
    );
    Ok(())
}

/// The texels of a lightmapped file relit (`values`, one per texel), written as an RGB
/// OpenEXR image beside the relit copy `output` (`glb::relit::RELIT_LIGHTMAP`); what the copy
/// says of it and where it went.
fn write_relit_lightmap(
    output: &Path,
    texels: &prt_gpu::bake::TexelBake,
    values: Vec<[f32; 3]>,
) -> Result<(glb::relit::RelitLightmap, PathBuf)> {
    let uri = glb::relit::relit_lightmap_file_name(output);
    let path = output.with_file_name(&uri);
    let pixels: Vec<[f32; 4]> = values.into_iter().map(|[r, g, b]| [r, g, b, 1.0]).collect();
    let (width, height) = (texels.width, texels.height);
    render::write_image(&path, &pixels, width, height, ToneMap::None, 0.0)?;
    let lightmap = glb::relit::RelitLightmap {
        uri,
        width,
        height,
        texcoord: texels.set,
    };
    Ok((lightmap, path))
}

/// The light `-o .glb` relights under, shaped, and its name for the file and the report.
fn relit_light(args: &RenderArgs, bands: u32) -> Result<(light::ShLight, String)> {
    let (light, name) = match &args.light {
        Some(light_path) => (
            load_light(light_path, bands, args.mapping, false)?.light,
            light_path.display().to_string(),
        ),
        None => (
            light::preview_light(bands)?,
            "the preview sky and sun".to_string(),
        ),
    };
    Ok((shape(light, &args.shaping), name))
}

/// `render SCENE.glb --light ... -o relit.glb` for a glTF scene baked in place: each baked
/// primitive's relit shading as `COLOR_0` under an unlit material, the radiance as
/// `_RADIANCE` (`glb::relit`).
fn write_relit_scene(args: &RenderArgs, path: &Path) -> Result<()> {
    let (gltf, baked) = glb::scene::read_scene_vertices(path)?;
    let (light, name) = relit_light(args, baked.metadata.bands)?;
    let lit = render::relight(&baked.transfer, &light)?;
    let radiance = render::apply_albedo(&baked, lit.clone());
    let shading = match baked.metadata.albedo_free {
        true => lit,
        false => radiance
            .iter()
            .zip(&baked.scene.albedo)
            .map(|(r, a)| std::array::from_fn(|c| over_albedo(r[c], a[c])))
            .collect(),
    };
    // A lightmapped scene (read again with its texels): their shading, as its vertices' is.
    let lightmapped = match glb::read_references(path)?.lightmap {
        Some(_) => Some(glb::scene::read_scene_glb(path)?),
        None => None,
    };
    let lightmap = match lightmapped
        .as_ref()
        .and_then(|b| Some((&b.scene, b.lightmap.as_ref()?)))
    {
        Some((scene, texels)) => {
            let relit = render::relight(&texels.transfer, &light)?;
            let shading = texel_shading(scene, texels, relit)?;
            Some(write_relit_lightmap(&args.output, texels, shading)?)
        }
        None => None,
    };
    let described = (
        name.as_str(),
        lightmap.as_ref().map(|(lightmap, _)| lightmap),
    );
    let scale = glb::relit::write_relit_scene_copy(
        path,
        &args.output,
        &gltf,
        &radiance,
        &shading,
        described,
    )
    .inspect_err(|_| remove_relit_lightmap(&lightmap))?;
    println!(
        "relit {} vertices of {} primitive(s) under {name} -> {} ({} = exit radiance; COLOR_0 \
         = exit radiance / albedo / {scale} under unlit materials (extras.prt.relit)){}",
        radiance.len(),
        gltf.instances
            .iter()
            .map(|i| i.primitives.len())
            .sum::<usize>(),
        args.output.display(),
        glb::relit::RADIANCE_ATTRIBUTE,
        relit_lightmap_line(&lightmap)
    );
    Ok(())
}

/// A scene's relit texels over the albedo each was baked with; gutter texels, which no
/// triangle covers, filled from their neighbours as the bake filled them.
fn texel_shading(
    scene: &prt_gpu::scene::Scene,
    texels: &prt_gpu::bake::TexelBake,
    relit: Vec<[f32; 3]>,
) -> Result<Vec<[f32; 3]>> {
    let (albedo, mut covered) = prt_gpu::bake::texels::texel_albedo(scene, texels);
    let mut values: Vec<f32> = relit
        .iter()
        .zip(&albedo)
        .flat_map(|(r, a)| [0, 1, 2].map(|c| over_albedo(r[c], a[c])))
        .collect();
    let (w, h) = (texels.width, texels.height);
    let passes = prt_gpu::bake::texels::DILATION_PASSES;
    prt_gpu::receivers::texels::dilate(w, h, &mut values, 3, &mut covered, passes)?;
    Ok(values.chunks_exact(3).map(|v| [v[0], v[1], v[2]]).collect())
}

/// Removes a relit lightmap whose copy could not be written: the two go together or not at all.
fn remove_relit_lightmap(lightmap: &Option<(glb::relit::RelitLightmap, PathBuf)>) {
    if let Some((_, written)) = lightmap {
        let _ = std::fs::remove_file(written);
    }
}

/// What the report says of a relit lightmap, if one was written.
fn relit_lightmap_line(lightmap: &Option<(glb::relit::RelitLightmap, PathBuf)>) -> String {
    match lightmap {
        Some((lightmap, written)) => format!(
            "; its {}x{} texels -> {} (extras.prt.relit.lightmap)",
            lightmap.width,
            lightmap.height,
            written.display()
        ),
        None => String::new(),
    }
}

/// Radiance over the albedo that made it; zero where the albedo is (nothing to show there).
fn over_albedo(radiance: f32, albedo: f32) -> f32 {
    match albedo > 0.0 {
        true => radiance / albedo,
        false => 0.0,
    }
}

/// `render` of a local-lights bake: one image, a sequence (`--frames`), or a relit copy.
/// The most frames one `render --frames` writes: seven minutes at 24 frames a second.
const MAX_FRAMES: u32 = 10_000;

fn run_local_render(args: &RenderArgs, path: &Path) -> Result<()> {
    let distant = args.light.is_some() || args.sky || !args.probe_sphere.is_empty();
    if distant || args.zonal || args.bend.is_some() {
        return Err(Error::Options(
            "--light, --sky, --probe-sphere, --zonal and --bend are distant light; a \
             local-lights bake takes --point-light and --spot-light"
                .into(),
        ));
    }
    let lights = parsed_lights(args)?;
    let baked = glb::local::read_local_glb(path)?;
    let relighter = local::Relighter::with_shadows(&baked, args.shadows.unwrap_or_default());
    if is_glb(&args.output) {
        return write_relit_local(args, path, &relighter, &lights);
    }
    let frames = frame_count(args, path)?;
    let camera = args
        .camera
        .unwrap_or_else(|| Camera::framing_scene(&baked.scene));
    let context = open_render_device(args.adapter.as_deref())?;
    let gpu = match args.device {
        DeviceChoice::Cpu => None,
        DeviceChoice::Gpu => GpuBaker::open(DeviceChoice::Gpu, args.adapter.as_deref())?,
        DeviceChoice::Auto => GpuBaker::open(DeviceChoice::Auto, args.adapter.as_deref())
            .ok()
            .flatten(),
    };
    let gpu_paths = match &gpu {
        Some(baker) => Some(local::GpuPaths::new(baker, &baked)?),
        None => None,
    };
    if let Some(Err(why)) = gpu_paths.as_ref().map(|paths| &paths.compressed) {
        eprintln!("the compressed operator is not timed on the GPU: {why}");
    }
    let (lo, hi) = render::bounds(&baked.scene.positions);
    let centre = args.orbit.unwrap_or((lo + hi) * 0.5);
    let mut timing = local::FrameTimes::default();
    let mut one_frame = |f: u32, output: &Path| -> Result<()> {
        let lights = local_lights::on_circle(&lights, centre, f, frames);
        let frame = local::time_frame(
            &relighter,
            &lights,
            args.operator,
            gpu_paths.as_ref(),
            &mut timing,
        )?;
        let image = render::render(
            &context,
            &baked.scene,
            &frame.total(),
            &camera,
            args.width,
            args.height,
        )?;
        render::write_image(
            output,
            &image,
            args.width,
            args.height,
            args.tone_map,
            args.exposure,
        )
    };
    let mut written = Vec::new();
    for f in 0..frames {
        let output = local::frame_path(&args.output, f, frames);
        if let Err(error) = one_frame(f, &output) {
            // A sequence is whole or not at all: the frames before the failed one go too.
            for path in &written {
                let _ = std::fs::remove_file(path);
            }
            return Err(error);
        }
        written.push(output);
    }
    println!(
        "rendered {frames} frame(s) of {}x{} -> {}",
        args.width,
        args.height,
        local::frame_path(&args.output, 0, frames).display()
    );
    println!(
        "{}",
        timing.report(
            baked.scene.positions.len(),
            relighter.shadows(),
            gpu.as_ref().map(|g| g.context.adapter.label())
        )
    );
    Ok(())
}

/// A local-lights bake relit under `lights`, written as a copy with the radiance as COLOR_0.
fn write_relit_local(
    args: &RenderArgs,
    path: &Path,
    relighter: &local::Relighter,
    lights: &[LocalLight],
) -> Result<()> {
    if args.frames.is_some() {
        return Err(Error::Options("--frames writes images, not .glb".into()));
    }
    let frame = relighter.frame(lights, args.operator);
    let name = local_lights::describe(lights);
    let scale = glb::relit::write_relit_copy(path, &args.output, &frame.total(), (&name, None))?;
    let shadows = relighter.shadows().describe();
    println!(
        "relit {} vertices under {name}, {} operator, shadows by {shadows} -> {} ({})",
        frame.direct.len(),
        match args.operator {
            OperatorForm::Compressed => "compressed",
            OperatorForm::Sparse => "sparse",
        },
        args.output.display(),
        relit_attributes(scale)
    );
    Ok(())
}

/// What a relit copy's colours hold, for the line that reports it.
fn relit_attributes(scale: f32) -> String {
    format!(
        "{} = exit radiance; COLOR_0 = exit radiance / {scale} (extras.prt.relit.scale)",
        glb::relit::RADIANCE_ATTRIBUTE
    )
}

/// `--frames` (1 when absent), within bounds, every frame's name checked against the bake
/// `path` it reads.
fn frame_count(args: &RenderArgs, path: &Path) -> Result<u32> {
    let frames = args.frames.unwrap_or(1);
    if frames == 0 || frames > MAX_FRAMES {
        return Err(Error::Options(format!(
            "--frames {frames} is out of range (1 to {MAX_FRAMES})"
        )));
    }
    for f in 0..frames {
        let frame = local::frame_path(&args.output, f, frames);
        let output = fs::Output {
            option: "-o",
            path: &frame,
        };
        fs::check_outputs(&[output], &[path])?;
    }
    Ok(frames)
}

/// What `render` writes — the image or the relit copy — checked before any work: named .png,
/// .exr or .glb (the name chooses the format), not a baked file, the light or a lightmap a
/// baked file reads, in a directory that exists. (The frames of a sequence are checked once
/// the file is known to be a local-lights bake.)
fn check_render_outputs(args: &RenderArgs) -> Result<()> {
    if args.bend.is_some() && is_glb(&args.output) {
        return Err(Error::Options(
            "--bend draws a bent mesh into an image; -o .glb writes a relit copy of the mesh \
             as baked"
                .into(),
        ));
    }
    if !args.probe_sphere.is_empty() && is_glb(&args.output) {
        return Err(Error::Options(
            "--probe-sphere draws test spheres into an image; -o .glb writes a relit copy of \
             the baked mesh"
                .into(),
        ));
    }
    let lightmaps: Vec<PathBuf> = args
        .baked
        .iter()
        .filter_map(|path| {
            let uri = glb::read_references(path).ok()?.lightmap?.uri;
            Some(path.with_file_name(uri))
        })
        .collect();
    let inputs: Vec<&Path> = args
        .baked
        .iter()
        .chain(&args.light)
        .chain(&lightmaps)
        .map(PathBuf::as_path)
        .collect();
    let output = fs::Output {
        option: "-o",
        path: &args.output,
    };
    // A relit copy of a lightmapped file writes its relit lightmap beside it.
    let relit_lightmap = args
        .output
        .with_file_name(glb::relit::relit_lightmap_file_name(&args.output));
    let beside = fs::Output {
        option: "-o (its relit lightmap)",
        path: &relit_lightmap,
    };
    match is_glb(&args.output) && !lightmaps.is_empty() {
        true => fs::check_outputs(&[output, beside], &inputs)?,
        false => fs::check_outputs(&[output], &inputs)?,
    }
    let mut formats = render::IMAGE_EXTENSIONS.to_vec();
    formats.push("glb");
    fs::check_named_format(
        fs::Output {
            option: "-o",
            path: &args.output,
        },
        &formats,
        "render writes an image (PNG or OpenEXR) or a relit copy of a baked file (binary glTF)",
    )?;
    fs::check_destination(&args.output)?;
    Ok(())
}

fn is_glb(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("glb"))
}

/// The lights given on the command line (at least one).
fn parsed_lights(args: &RenderArgs) -> Result<Vec<LocalLight>> {
    let mut lights = Vec::new();
    for text in &args.point_light {
        lights.push(local_lights::parse_point_light(text)?);
    }
    for text in &args.spot_light {
        lights.push(local_lights::parse_spot_light(text)?);
    }
    if lights.is_empty() {
        return Err(Error::Options(
            "a local-lights bake needs --point-light or --spot-light".into(),
        ));
    }
    Ok(lights)
}
