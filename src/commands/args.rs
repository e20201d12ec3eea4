//! Option types and parsers that several commands share.

use glam::Vec3;

use prt_gpu::bake::{self, BakeOptions, Mode, DEFAULT_SAMPLES, DEFAULT_SAMPLING};
use prt_gpu::sampling::Sampling;
use prt_gpu::sh::window::Window;
use prt_gpu::spec::Compression;

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

use prt_gpu::spec::AUTO_MAX_BANDS;

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
    #[arg(long, value_parser = parse_angles, allow_hyphen_values = true)]
    pub(crate) rotate: Option<Vec3>,
}

pub(crate) fn parse_compression(text: &str) -> std::result::Result<Compression, String> {
    match text.strip_prefix("auto:") {
        Some(target) => target
            .trim()
            .parse::<f64>()
            .map(|error| Compression::Target { error })
            .map_err(|e| format!("expected auto:ERROR, such as auto:0.02: {e}")),
        None => parse_cpca_shape(text).map(|(clusters, components)| Compression::Shape {
            clusters,
            components,
        }),
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

/// One finite number.
pub(crate) fn parse_finite(text: &str) -> std::result::Result<f32, String> {
    match text.trim().parse::<f32>() {
        Ok(value) if value.is_finite() => Ok(value),
        _ => Err("expected a finite number".into()),
    }
}

/// Three finite numbers, named `names` (e.g. `X,Y,Z`) in the error.
fn parse_triple(text: &str, names: &str) -> std::result::Result<Vec3, String> {
    let values: Option<Vec<f32>> = text
        .split(',')
        .map(|part| part.trim().parse::<f32>().ok().filter(|v| v.is_finite()))
        .collect();
    match values.as_deref() {
        Some(&[a, b, c]) => Ok(Vec3::new(a, b, c)),
        _ => Err(format!("expected three finite numbers {names}")),
    }
}

pub(crate) fn parse_point(text: &str) -> std::result::Result<Vec3, String> {
    parse_triple(text, "X,Y,Z")
}

/// `--probe-sphere X,Y,Z[,R]`: a centre and, where given, a positive radius.
pub(crate) fn parse_sphere(text: &str) -> std::result::Result<(Vec3, Option<f32>), String> {
    let expected = "expected X,Y,Z[,R]: three finite numbers and an optional positive radius";
    match text.rsplit_once(',') {
        Some((centre, radius)) if centre.matches(',').count() == 2 => {
            let radius: f32 = radius.trim().parse().map_err(|_| expected.to_string())?;
            if !(radius.is_finite() && radius > 0.0) {
                return Err(expected.into());
            }
            Ok((parse_triple(centre, "X,Y,Z")?, Some(radius)))
        }
        _ => Ok((
            parse_triple(text, "X,Y,Z").map_err(|_| expected.to_string())?,
            None,
        )),
    }
}

/// A direction towards a light: not the zero vector.
pub(crate) fn parse_direction(text: &str) -> std::result::Result<Vec3, String> {
    let direction = parse_triple(text, "X,Y,Z (a direction)")?;
    match direction == Vec3::ZERO {
        true => Err("a direction cannot be 0,0,0".into()),
        false => Ok(direction),
    }
}

/// `--rotate`'s Euler angles in degrees.
pub(crate) fn parse_angles(text: &str) -> std::result::Result<Vec3, String> {
    parse_triple(text, "YAW,PITCH,ROLL (degrees)")
}

/// R,G,B or one grey value, finite.
pub(crate) fn parse_rgb(text: &str) -> std::result::Result<Vec3, String> {
    match text.split(',').count() {
        1 => match text.trim().parse::<f32>() {
            Ok(grey) if grey.is_finite() => Ok(Vec3::splat(grey)),
            _ => Err("expected R,G,B or one grey value, finite".into()),
        },
        _ => parse_triple(text, "R,G,B (or one grey value)"),
    }
}

/// Radiance, irradiance or intensity: [`parse_rgb`], none of it negative.
pub(crate) fn parse_radiance(text: &str) -> std::result::Result<Vec3, String> {
    let rgb = parse_rgb(text)?;
    match rgb.min_element() < 0.0 {
        true => Err("light cannot be negative".into()),
        false => Ok(rgb),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn triples_take_three_finite_numbers_and_say_which() {
        assert_eq!(parse_point(" 1, -2,3 "), Ok(Vec3::new(1.0, -2.0, 3.0)));
        for bad in ["1,2", "1,2,3,4", "1,nan,3", "inf,0,0", "a,b,c", ""] {
            assert_eq!(
                parse_point(bad),
                Err("expected three finite numbers X,Y,Z".into()),
                "{bad:?}"
            );
        }
        assert!(parse_angles("30").unwrap_err().contains("YAW,PITCH,ROLL"));
        assert_eq!(
            parse_direction("0,0,0"),
            Err("a direction cannot be 0,0,0".into())
        );
        assert_eq!(parse_direction("0,0,-1"), Ok(-Vec3::Z));
    }

    #[test]
    fn colours_are_one_grey_or_three_finite_and_light_is_not_negative() {
        assert_eq!(parse_rgb("0.5"), Ok(Vec3::splat(0.5)));
        assert_eq!(parse_rgb("1,0,0"), Ok(Vec3::X));
        assert!(parse_rgb("nan").is_err());
        assert!(parse_rgb("1,2").unwrap_err().contains("R,G,B"));
        assert_eq!(parse_radiance("0"), Ok(Vec3::ZERO));
        assert_eq!(parse_radiance("-3"), Err("light cannot be negative".into()));
        assert_eq!(
            parse_radiance("1,-1,1"),
            Err("light cannot be negative".into())
        );
    }
}
