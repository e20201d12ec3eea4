//! Option types and parsers that several commands share.

use glam::Vec3;

use prt_gpu::bake::{self, BakeOptions, Mode, DEFAULT_SAMPLES, DEFAULT_SAMPLING};
use prt_gpu::sampling::Sampling;
use prt_gpu::sh::window::Window;

/// What `bake` and `bench` compute per vertex.
#[derive(clap::Args)]
pub(crate) struct TransferArgs {
    /// Spherical-harmonic bands (bands^2 coefficients per channel), or `auto` (bake only): the
    /// fewest bands, up to 8, that leave less than --bands-threshold of the transfer's energy
    /// above them.
    #[arg(long, default_value = "4", value_parser = parse_bands)]
    pub(crate) bands: Bands,
    /// Sample directions per vertex (rounded to the nearest square for stratified sampling).
    /// Default 1024; 256 gather rays per receiver with --mode local.
    #[arg(long)]
    pub(crate) samples: Option<u32>,
    /// How sample directions are drawn and weighted. cosine (the default) casts every ray above
    /// the horizon, with the cosine in its density; see `prt-gpu chart`.
    #[arg(long, value_enum, default_value_t = DEFAULT_SAMPLING)]
    pub(crate) sampling: Sampling,
    /// Light transport to capture.
    #[arg(long, value_enum, default_value_t = Mode::Shadowed)]
    pub(crate) mode: Mode,
}

/// `--bands`: a count, or chosen from the transfer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Bands {
    Fixed(u32),
    Auto,
}

/// The most bands `--bands auto` bakes and chooses among.
pub(crate) const AUTO_MAX_BANDS: u32 = 8;

fn parse_bands(text: &str) -> std::result::Result<Bands, String> {
    if text.eq_ignore_ascii_case("auto") {
        return Ok(Bands::Auto);
    }
    text.parse::<u32>()
        .map(Bands::Fixed)
        .map_err(|e| format!("expected a number of bands or auto: {e}"))
}

impl TransferArgs {
    /// Bake options with these settings and defaults for the rest (`auto` bands bake the most
    /// it chooses among).
    pub(crate) fn options(&self) -> BakeOptions {
        BakeOptions {
            bands: match self.bands {
                Bands::Fixed(bands) => bands,
                Bands::Auto => AUTO_MAX_BANDS,
            },
            samples: self.samples.unwrap_or(DEFAULT_SAMPLES),
            sampling: self.sampling,
            mode: self.mode,
            ..BakeOptions::default()
        }
    }
}

/// How a light is post-processed, shared by `light` and `render`.
#[derive(clap::Args)]
pub(crate) struct LightShaping {
    /// Ringing control: none, hanning, lanczos, or non-negative (the least smoothing that
    /// leaves no negative radiance anywhere).
    #[arg(long, value_enum, default_value_t = Window::None)]
    pub(crate) window: Window,
    /// Rotate the light: yaw (about +Y), pitch (about +X), roll (about +Z), in degrees.
    #[arg(long, value_parser = parse_rgb, allow_hyphen_values = true)]
    pub(crate) rotate: Option<Vec3>,
}

/// `--compress`: a shape, or an error target to choose one by.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Compression {
    Shape(u32, u32),
    Target(f64),
}

pub(crate) fn parse_compression(text: &str) -> std::result::Result<Compression, String> {
    match text.strip_prefix("auto:") {
        Some(target) => target
            .trim()
            .parse::<f64>()
            .map(Compression::Target)
            .map_err(|e| format!("expected auto:ERROR, such as auto:0.02: {e}")),
        None => parse_cpca_shape(text).map(|(k, m)| Compression::Shape(k, m)),
    }
}

pub(crate) fn parse_size(text: &str) -> std::result::Result<u64, String> {
    let text = text.trim();
    let split = text
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(text.len());
    let (number, unit) = text.split_at(split);
    let shift = match unit
        .trim()
        .to_ascii_uppercase()
        .trim_end_matches("IB")
        .trim_end_matches('B')
    {
        "" => 0,
        "K" => 10,
        "M" => 20,
        "G" => 30,
        "T" => 40,
        _ => return Err(format!("expected a size such as 512M or 8G, not {text}")),
    };
    match number.parse::<f64>() {
        Ok(value) if value > 0.0 && value.is_finite() => {
            Ok((value * (1u64 << shift) as f64) as u64)
        }
        _ => Err(format!("expected a size such as 512M or 8G, not {text}")),
    }
}

pub(crate) fn parse_shard(text: &str) -> std::result::Result<bake::Shard, String> {
    let numbers = text
        .split_once('/')
        .and_then(|(i, n)| Some((i.trim().parse::<u32>().ok()?, n.trim().parse::<u32>().ok()?)));
    let Some((index, count)) = numbers else {
        return Err("expected I/N, shard I of N counted from 0 (e.g. 0/4)".into());
    };
    bake::Shard::new(index, count).map_err(|e| e.to_string())
}

pub(crate) fn parse_cpca_shape(text: &str) -> std::result::Result<(u32, u32), String> {
    let (clusters, components) = text
        .split_once(['x', 'X'])
        .ok_or("expected CLUSTERSxCOMPONENTS, such as 64x8")?;
    let number = |t: &str| {
        t.trim()
            .parse::<u32>()
            .map_err(|e| format!("expected CLUSTERSxCOMPONENTS, such as 64x8: {e}"))
    };
    Ok((number(clusters)?, number(components)?))
}

pub(crate) fn parse_point(text: &str) -> std::result::Result<Vec3, String> {
    let v = text
        .split(',')
        .map(|part| part.trim().parse::<f32>())
        .collect::<std::result::Result<Vec<f32>, _>>()
        .map_err(|e| format!("expected X,Y,Z: {e}"))?;
    match v[..] {
        [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok(Vec3::new(x, y, z)),
        _ => Err("expected three finite numbers X,Y,Z".into()),
    }
}

pub(crate) fn parse_rgb(text: &str) -> std::result::Result<Vec3, String> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    let values: std::result::Result<Vec<f32>, _> = match parts.len() {
        1 => parts[0].parse::<f32>().map(|v| vec![v; 3]),
        3 => parts.iter().map(|p| p.parse::<f32>()).collect(),
        _ => return Err("expected R,G,B (or one grey value)".into()),
    };
    let v = values.map_err(|e| format!("expected numbers: {e}"))?;
    Ok(Vec3::new(v[0], v[1], v[2]))
}
