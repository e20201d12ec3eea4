//! light.json: SH lighting coefficients with the basis convention they were computed in.
//!
//! ```json
//! { "convention": "<sh::CONVENTION>", "bands": 3, "coeffs": [[r, g, b], ...] }
//! ```

use super::ShLight;
use crate::error::{Error, Result};
use crate::sh;
use serde::{Deserialize, Serialize};
use std::path::Path;

#[derive(Serialize, Deserialize)]
struct LightFile {
    convention: String,
    bands: u32,
    coeffs: Vec<[f32; 3]>,
}

/// Writes `light` as JSON through a temporary file in the same directory, renamed into place,
/// so an interrupted write never leaves a truncated light.json behind.
pub fn write_json(path: &Path, light: &ShLight) -> Result<()> {
    validate(light).map_err(|m| Error::light(path, m))?;
    let file = LightFile {
        convention: sh::CONVENTION.to_string(),
        bands: light.bands,
        coeffs: light.coeffs.clone(),
    };
    let text =
        serde_json::to_string_pretty(&file).map_err(|e| Error::light(path, e.to_string()))?;
    crate::fs::write_atomically(path, format!("{text}\n").as_bytes())
}

/// Reads and checks a light.json: our convention, `bands^2` coefficients, all finite.
pub fn read_json(path: &Path) -> Result<ShLight> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let file: LightFile = serde_json::from_str(&text)
        .map_err(|e| Error::light(path, format!("not a light file: {e}")))?;
    if file.convention != sh::CONVENTION {
        return Err(Error::light(
            path,
            format!(
                "written in SH convention \"{}\", this program uses \"{}\"",
                file.convention,
                sh::CONVENTION
            ),
        ));
    }
    let light = ShLight {
        bands: file.bands,
        coeffs: file.coeffs,
    };
    validate(&light).map_err(|m| Error::light(path, m))?;
    Ok(light)
}

fn validate(light: &ShLight) -> std::result::Result<(), String> {
    if light.bands == 0 || light.bands > sh::MAX_BANDS {
        return Err(format!(
            "bands must be between 1 and {}, not {}",
            sh::MAX_BANDS,
            light.bands
        ));
    }
    let expected = sh::coeff_count(light.bands);
    if light.coeffs.len() != expected {
        return Err(format!(
            "{} bands need {expected} coefficients, found {}",
            light.bands,
            light.coeffs.len()
        ));
    }
    if let Some(k) = light
        .coeffs
        .iter()
        .position(|c| !c.iter().all(|v| v.is_finite()))
    {
        return Err(format!("coefficient {k} is not finite"));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_with_the_convention() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("light.json");
        let light = ShLight {
            bands: 2,
            coeffs: vec![
                [1.0, 2.0, 3.0],
                [-0.5, 0.25, 1e-8],
                [0.0; 3],
                [1e30, -1e-30, 7.0],
            ],
        };
        write_json(&path, &light).unwrap();
        assert_eq!(read_json(&path).unwrap(), light);
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.contains(sh::CONVENTION));
        let leftovers: Vec<_> = std::fs::read_dir(path.parent().unwrap())
            .unwrap()
            .filter_map(|e| e.ok())
            .filter(|e| e.file_name().to_string_lossy().contains(".tmp"))
            .collect();
        assert!(leftovers.is_empty());
    }

    #[test]
    fn rejects_damaged_files() {
        let cases = [
            (
                "count.json",
                format!(
                    r#"{{"convention":"{}","bands":2,"coeffs":[[1,2,3]]}}"#,
                    sh::CONVENTION
                ),
                "need 4",
            ),
            (
                "conv.json",
                r#"{"convention":"other","bands":1,"coeffs":[[1,2,3]]}"#.to_string(),
                "convention",
            ),
            ("junk.json", "{".to_string(), "not a light file"),
            (
                "big.json",
                format!(
                    r#"{{"convention":"{}","bands":1,"coeffs":[[1e39,0,0]]}}"#,
                    sh::CONVENTION
                ),
                "",
            ),
        ];
        let dir = tempfile::tempdir().unwrap();
        for (name, text, needle) in cases {
            let path = dir.path().join(name);
            std::fs::write(&path, text).unwrap();
            let e = read_json(&path).unwrap_err().to_string();
            assert!(e.contains(needle) && !e.contains('\n'), "{name}: {e}");
        }
        let nan = ShLight {
            bands: 1,
            coeffs: vec![[f32::NAN, 0.0, 0.0]],
        };
        let path = dir.path().join("nan.json");
        assert!(write_json(&path, &nan)
            .unwrap_err()
            .to_string()
            .contains("not finite"));
        assert!(!path.exists());
    }
}
