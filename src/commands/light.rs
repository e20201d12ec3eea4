//! `prt-gpu light`: lighting projected onto SH.

use std::path::{Path, PathBuf};

use glam::Vec3;

use super::args::{parse_direction, parse_radiance, LightShaping};
use prt_gpu::light::{self, analytic, LoadedLight, Mapping, ShLight};
use prt_gpu::sh::MAX_BANDS;
use prt_gpu::{fs, Error, Result};

#[derive(clap::Args)]
pub(crate) struct LightArgs {
    /// Environment map: OpenEXR, Radiance .hdr, PNG or JPEG; or a light.json, to rotate or
    /// window it.
    envmap: Option<PathBuf>,
    /// SH bands of the light.
    #[arg(long, default_value_t = 4)]
    bands: u32,
    /// How the map's pixels map to directions (auto-detected from the aspect ratio when it
    /// is unambiguous: 2:1 lat-long, 4:3 and 3:4 cube crosses).
    #[arg(long, value_enum)]
    mapping: Option<Mapping>,
    /// Give NaN or infinite pixels zero weight instead of failing.
    #[arg(long)]
    skip_invalid: bool,
    /// A cube map as six separate faces: +X,-X,+Y,-Y,+Z,-Z image paths, comma-separated.
    #[arg(long, value_delimiter = ',', conflicts_with = "envmap")]
    faces: Vec<PathBuf>,
    /// Add a directional light (a delta): direction X,Y,Z towards the light.
    #[arg(long, value_parser = parse_direction, allow_hyphen_values = true)]
    directional: Option<Vec3>,
    /// Irradiance of --directional (R,G,B or one value).
    #[arg(long, value_parser = parse_radiance, default_value = "1")]
    directional_intensity: Vec3,
    /// Add a sun: direction X,Y,Z (towards the sun).
    #[arg(long, value_parser = parse_direction, allow_hyphen_values = true)]
    sun: Option<Vec3>,
    /// Sun disk half-angle in degrees.
    #[arg(long, default_value_t = 0.27)]
    sun_angle: f64,
    /// Sun irradiance (R,G,B or one value).
    #[arg(long, value_parser = parse_radiance, default_value = "3")]
    sun_irradiance: Vec3,
    /// Add a sky of this radiance above the horizon (R,G,B).
    #[arg(long, value_parser = parse_radiance)]
    sky: Option<Vec3>,
    /// Ground radiance below the horizon, with --sky.
    #[arg(long, value_parser = parse_radiance, default_value = "0")]
    ground: Vec3,
    /// Add constant ambient radiance (R,G,B).
    #[arg(long, value_parser = parse_radiance)]
    ambient: Option<Vec3>,
    /// Add the tutorial's two-light test function.
    #[arg(long)]
    tutorial: bool,
    #[command(flatten)]
    shaping: LightShaping,
    /// Output light.json.
    #[arg(short, long, default_value = "light.json")]
    output: PathBuf,
}

pub(crate) fn run_light(args: LightArgs) -> Result<()> {
    let bands = args.bands;
    if bands == 0 || bands > MAX_BANDS {
        return Err(Error::Options(format!(
            "--bands {bands} is out of range (1 to {MAX_BANDS})"
        )));
    }
    if !(args.sun_angle > 0.0 && args.sun_angle <= 180.0) {
        return Err(Error::Options(format!(
            "--sun-angle {} must lie in (0, 180] degrees",
            args.sun_angle
        )));
    }
    let output = fs::Output {
        option: "-o",
        path: &args.output,
    };
    let inputs: Vec<&Path> = args
        .envmap
        .iter()
        .chain(&args.faces)
        .map(PathBuf::as_path)
        .collect();
    fs::check_output(output, &inputs, &["json"], "a light is written as JSON")?;
    let mut total = ShLight::constant(bands, [0.0; 3]);
    let mut parts = Vec::new();
    if let Some(path) = &args.envmap {
        let loaded = load_light(path, bands, args.mapping, args.skip_invalid)?;
        note_skipped_pixels(loaded.skipped_pixels);
        // A light.json has no mapping: it is taken as it is (then rotated and windowed).
        parts.push(match loaded.mapping {
            Some(mapping) => format!("{} ({mapping:?})", path.display()),
            None => path.display().to_string(),
        });
        total = total.plus(&loaded.light)?;
    }
    if !args.faces.is_empty() {
        let loaded = light::load_faces(&args.faces, bands, args.skip_invalid)?;
        say_warnings(&loaded.warnings);
        note_skipped_pixels(loaded.skipped_pixels);
        total = total.plus(&loaded.light)?;
        parts.push("six cube faces".into());
    }
    if let Some(direction) = args.directional {
        let light = analytic::directional(
            bands,
            direction.as_dvec3(),
            args.directional_intensity.to_array(),
        )?;
        total = total.plus(&light)?;
        parts.push("directional".into());
    }
    if let Some(direction) = args.sun {
        let sun = analytic::sun_disk(
            bands,
            direction.as_dvec3(),
            args.sun_angle.to_radians(),
            args.sun_irradiance.to_array(),
        )?;
        total = total.plus(&sun)?;
        parts.push("sun".into());
    }
    if let Some(sky) = args.sky {
        total = total.plus(&analytic::hemisphere(
            bands,
            sky.to_array(),
            args.ground.to_array(),
        )?)?;
        parts.push("sky".into());
    }
    if let Some(ambient) = args.ambient {
        total = total.plus(&ShLight::constant(bands, ambient.to_array()))?;
        parts.push("ambient".into());
    }
    if args.tutorial {
        total = total.plus(&analytic::tutorial_two_lights(bands)?)?;
        parts.push("tutorial two lights".into());
    }
    if parts.is_empty() {
        return Err(Error::Options(
            "give an environment map (or --faces) or at least one of --directional, --sun, \
             --sky, --ambient, --tutorial"
                .into(),
        ));
    }
    let light = shape(total, &args.shaping);
    light::write_json(&args.output, &light)?;
    println!(
        "projected {} onto {bands} bands (DC {:.4} {:.4} {:.4}) -> {}",
        parts.join(" + "),
        light.coeffs[0][0],
        light.coeffs[0][1],
        light.coeffs[0][2],
        args.output.display()
    );
    Ok(())
}

/// A light from a file (`light::load`), its warnings said.
pub(crate) fn load_light(
    path: &Path,
    bands: u32,
    mapping: Option<Mapping>,
    skip_invalid: bool,
) -> Result<LoadedLight> {
    let loaded = light::load(path, bands, mapping, skip_invalid)?;
    say_warnings(&loaded.warnings);
    Ok(loaded)
}

/// One `warning:` line each.
pub(crate) fn say_warnings(warnings: &[String]) {
    for warning in warnings {
        eprintln!("warning: {warning}");
    }
}

fn note_skipped_pixels(skipped: usize) {
    if skipped > 0 {
        eprintln!("note: skipped {skipped} NaN or infinite pixels");
    }
}

/// Rotation first, then windowing, so the window sees the light as it will be used.
pub(crate) fn shape(light: ShLight, shaping: &LightShaping) -> ShLight {
    let light = match shaping.rotate {
        Some(r) => light.rotated(r.x as f64, r.y as f64, r.z as f64),
        None => light,
    };
    light.windowed(shaping.window)
}
