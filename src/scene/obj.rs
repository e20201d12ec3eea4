//! Wavefront OBJ reader (through tobj). All objects and groups become one [`Scene`].
//!
//! Albedo comes from the diffuse colour (Kd) of each object's material. A missing or
//! unreadable MTL file, or an object without a material, gives [`DEFAULT_ALBEDO`]: an OBJ is
//! routinely copied without its MTL, and refusing to bake it would help no one.
//!
//! The text is tidied before tobj reads it, as other OBJ readers do: a UTF-8 byte-order mark
//! is skipped, a `#` comment after a statement is dropped, and a line ending in `\` continues
//! on the next. Its statements are then checked here, so that an error names its line.

use std::borrow::Cow;
use std::collections::BTreeSet;
use std::path::Path;
use std::str::FromStr;

use glam::Vec3;

use super::{Scene, DEFAULT_ALBEDO};
use crate::error::{Error, Result};

/// Reads an OBJ file and the MTL files it names (relative to the OBJ's directory).
///
/// Polygons are fan-triangulated; points and lines are ignored (they bound no surface).
/// Normals are kept only if every object has one per vertex; otherwise `prepare` computes
/// them for the whole mesh, so that no object is shaded differently from its neighbours.
pub fn load(path: &Path) -> Result<Scene> {
    load_with_warnings(path).map(|(scene, _)| scene)
}

/// [`load`], also giving a line for each material whose Kd had to be brought into [0, 1].
pub fn load_with_warnings(path: &Path) -> Result<(Scene, Vec<String>)> {
    let fail = |message: String| Error::mesh(path, format!("cannot read OBJ: {message}"));
    let (text, encoding) = {
        // The file's bytes go before tobj reads: a large OBJ is held twice at most.
        let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
        let (text, encoding) = file_text(&bytes).map_err(fail)?;
        (tidy(&text), encoding)
    };
    check_statements(&text).map_err(fail)?;
    let directory = path.parent().unwrap_or(Path::new("")).to_path_buf();
    let options = tobj::LoadOptions {
        triangulate: true,
        // One index per vertex, as the baker needs; tobj splits vertices whose position,
        // normal and texture coordinate indices differ, and prepare welds them again.
        single_index: true,
        ignore_points: true,
        ignore_lines: true,
    };
    let (models, materials) = tobj::load_obj_buf(&mut text.text.as_bytes(), &options, |mtl_path| {
        load_mtl(&directory.join(mtl_path))
    })
    .map_err(|e| fail(e.to_string()))?;
    let (materials, unread) = match materials {
        Ok(materials) => (materials, None),
        Err(e) => (
            Vec::new(),
            Some(format!(
                "its material library was not read ({e}); every face takes the default albedo"
            )),
        ),
    };
    let (scene, mut warnings) = merge_models(&models, &materials);
    warnings.extend(encoding.into_iter().chain(unread));
    if scene.triangles.is_empty() {
        return Err(Error::mesh(path, "no faces"));
    }
    Ok((scene, warnings))
}

/// An MTL file, tidied like the OBJ; errors as `tobj::load_mtl` gives them (an unreadable
/// file is no material library, not a failed OBJ).
fn load_mtl(path: &Path) -> tobj::MTLLoadResult {
    let bytes = std::fs::read(path).map_err(|_| tobj::LoadError::OpenFileFailed)?;
    let (text, _) = file_text(&bytes).map_err(|_| tobj::LoadError::ReadError)?;
    let colours = whole_colours(&tidy(&text).text).ok_or(tobj::LoadError::MaterialParseError)?;
    tobj::load_mtl_buf(&mut colours.as_bytes())
}

/// MTL text with every colour statement (`Ka`, `Kd`, `Ks`, `Ke`) of one or two numbers given
/// all three: green and blue default to red, as the format has it (tobj panics on fewer than
/// three). `None` for a colour statement with no value, which tobj would panic on too.
fn whole_colours(text: &str) -> Option<String> {
    let mut out = String::with_capacity(text.len());
    for line in text.lines() {
        let mut words = line.split_whitespace();
        let keyword = words.next();
        let values: Vec<&str> = words.collect();
        match keyword {
            Some("Ka" | "Kd" | "Ks" | "Ke") if values.len() < 3 => {
                let red = values.first()?;
                let given = values.iter().copied();
                let padded: Vec<&str> = given.chain(std::iter::repeat(*red)).take(3).collect();
                out.push_str(&format!("{} {}", keyword?, padded.join(" ")));
            }
            _ => out.push_str(line),
        }
        out.push('\n');
    }
    Some(out)
}

/// The file as text, without a byte-order mark, and what to say of how it was read: UTF-8,
/// or where it is not, Latin-1 (ISO 8859-1, every byte one character), as assimp and Blender
/// read it, so that material names in Latin-1 keep matching between the OBJ and its MTL.
fn file_text(bytes: &[u8]) -> std::result::Result<(Cow<'_, str>, Option<String>), String> {
    if bytes.starts_with(b"\xFF\xFE") || bytes.starts_with(b"\xFE\xFF") {
        return Err("the file is UTF-16 text; save it as UTF-8".into());
    }
    let bytes = super::skip_bom(bytes);
    match std::str::from_utf8(bytes) {
        Ok(text) => Ok((Cow::Borrowed(text), None)),
        Err(e) => {
            let line = 1 + bytes[..e.valid_up_to()]
                .iter()
                .filter(|&&b| b == b'\n')
                .count();
            let latin1: String = bytes.iter().map(|&b| char::from(b)).collect();
            let said = format!("line {line} is not UTF-8 text; the file was read as Latin-1");
            Ok((Cow::Owned(latin1), Some(said)))
        }
    }
}

/// OBJ text as tobj reads it: one statement a line, without comments.
struct Tidied {
    text: String,
    /// The line of the file each line of `text` starts on (1-based).
    lines: Vec<usize>,
}

/// `text` with comments dropped (from a `#` that starts the line or follows white space, to
/// the end of the line) and lines ending in `\` joined to the next, as the OBJ format has it.
/// A `\` inside a comment continues nothing.
fn tidy(text: &str) -> Tidied {
    let mut tidied = Tidied {
        text: String::with_capacity(text.len()),
        lines: Vec::new(),
    };
    let mut continued = false;
    for (index, line) in text.split('\n').enumerate() {
        let line = line.strip_suffix('\r').unwrap_or(line);
        let mut kept = without_comment(line).trim_end();
        if !continued {
            tidied.lines.push(index + 1);
        }
        continued = kept.ends_with('\\');
        if continued {
            kept = &kept[..kept.len() - 1];
        }
        match kept.trim() {
            // Blender writes a material without a name as `newmtl ` and `usemtl `; tobj
            // refuses the one and ignores the other, so both are given one name.
            keyword @ ("newmtl" | "usemtl") if !continued => {
                tidied
                    .text
                    .push_str(&format!("{keyword} {UNNAMED_MATERIAL}"));
            }
            _ => tidied.text.push_str(kept),
        }
        tidied.text.push(if continued { ' ' } else { '\n' });
    }
    tidied
}

/// What an empty material name is read as: no name a file can spell (DEL is not white space
/// to tobj, and no exporter writes it).
const UNNAMED_MATERIAL: &str = "\u{7f}unnamed";

fn without_comment(line: &str) -> &str {
    let mut previous_is_space = true;
    for (at, c) in line.char_indices() {
        if c == '#' && previous_is_space {
            return &line[..at];
        }
        previous_is_space = c.is_whitespace();
    }
    line
}

/// Checks the statements tobj would refuse (numbers that do not parse, face corners that are
/// not indices or point past the data), so that the error names the line; tobj's own checks
/// stay behind these. A face may use vertices given after it, as tobj allows.
fn check_statements(tidied: &Tidied) -> std::result::Result<(), String> {
    const DATA: [&str; 3] = ["v", "vt", "vn"];
    let mut totals = [0usize; 3];
    for line in tidied.text.lines() {
        let keyword = line.split_whitespace().next();
        if let Some(kind) = DATA.iter().position(|&k| Some(k) == keyword) {
            totals[kind] += 1;
        }
    }
    let mut so_far = [0usize; 3];
    for (line, &number) in tidied.text.lines().zip(&tidied.lines) {
        let at = |message: String| format!("line {number}: {message}");
        let mut words = line.split_whitespace();
        let keyword = words.next();
        let numbers = |n: usize, what: &str| -> std::result::Result<(), String> {
            let read = line.split_whitespace().skip(1).take(n);
            if read.filter(|v| f32::from_str(v).is_ok()).count() < n {
                return Err(at(format!("{what} needs {n} numbers: {:?}", line.trim())));
            }
            Ok(())
        };
        match keyword {
            Some("v") => {
                numbers(3, "a vertex")?;
                so_far[0] += 1;
            }
            Some("vt") => {
                numbers(2, "a texture coordinate")?;
                so_far[1] += 1;
            }
            Some("vn") => {
                numbers(3, "a normal")?;
                so_far[2] += 1;
            }
            Some(kind @ ("f" | "l")) => {
                // Points and lines are parsed but never placed, so tobj checks no range there.
                let is_face = kind == "f" && words.clone().count() >= 3;
                for corner in words {
                    let indices = corner_indices(corner).ok_or_else(|| {
                        at(format!(
                            "{corner:?} is not a vertex reference (v, v/vt, v//vn or v/vt/vn)"
                        ))
                    })?;
                    if is_face {
                        check_corner(indices, so_far, totals).map_err(at)?;
                    }
                }
            }
            _ => {}
        }
    }
    Ok(())
}

/// The (position, texture coordinate, normal) indices of a face corner as written: zero
/// where absent (never the position).
fn corner_indices(corner: &str) -> Option<[i64; 3]> {
    let mut indices = [0i64; 3];
    if corner.starts_with('/') {
        return None;
    }
    let mut parts = corner.split('/');
    for (slot, part) in indices.iter_mut().zip(parts.by_ref()) {
        if !part.is_empty() {
            // tobj reads indices as isize.
            *slot = isize::from_str(part).ok()? as i64;
        }
    }
    // tobj reads past a fourth, empty part (`1/2/3/`), and refuses anything in it.
    parts.all(str::is_empty).then_some(indices)
}

/// One corner's indices against the data: a negative index counts back from the data given
/// so far, a positive one may reach any in the file.
fn check_corner(
    indices: [i64; 3],
    so_far: [usize; 3],
    totals: [usize; 3],
) -> std::result::Result<(), String> {
    const NAMES: [&str; 3] = ["vertex", "texture coordinate", "normal"];
    for kind in 0..3 {
        let (index, total) = (indices[kind], totals[kind]);
        let name = NAMES[kind];
        // tobj ignores texture and normal indices when the file has none, and reads a 0
        // there as no index; a 0 vertex index it refuses.
        if kind > 0 && (total == 0 || index == 0) {
            continue;
        }
        if index == 0 {
            return Err("vertex index 0 (OBJ indices start at 1)".into());
        }
        if index < 0 && index.unsigned_abs() > so_far[kind] as u64 {
            return Err(format!(
                "{name} index {index} reaches before the first {name} ({} given so far)",
                so_far[kind]
            ));
        }
        if index > 0 && index as u64 > total as u64 {
            return Err(format!(
                "{name} index {index} is out of range (the file has {total})"
            ));
        }
    }
    Ok(())
}

/// The models as one scene, and a warning for each material whose Kd was out of range.
fn merge_models(models: &[tobj::Model], materials: &[tobj::Material]) -> (Scene, Vec<String>) {
    let every_model_has_normals = models
        .iter()
        .all(|m| m.mesh.normals.len() == m.mesh.positions.len());
    let mut scene = Scene {
        normals: every_model_has_normals.then(Vec::new),
        ..Scene::default()
    };
    let mut repaired = BTreeSet::new();
    for model in models {
        let mesh = &model.mesh;
        // Saturating keeps an impossible overflow visible as out-of-range indices.
        let offset = u32::try_from(scene.positions.len()).unwrap_or(u32::MAX);
        scene.positions.extend(vec3s(&mesh.positions));
        let material = mesh
            .material_id
            .and_then(|id| materials.get(id).map(|m| (id, m)));
        let albedo = match material.and_then(|(id, m)| m.diffuse.map(|kd| (id, kd))) {
            Some((id, kd)) => {
                let albedo = albedo_from_kd(kd);
                if albedo.to_array() != kd {
                    repaired.insert(id);
                }
                albedo
            }
            None => DEFAULT_ALBEDO,
        };
        scene.albedo.resize(scene.positions.len(), albedo);
        if let Some(normals) = scene.normals.as_mut() {
            normals.extend(vec3s(&mesh.normals));
        }
        scene.triangles.extend(
            mesh.indices
                .chunks_exact(3)
                .map(|t| [t[0], t[1], t[2]].map(|i| i.saturating_add(offset))),
        );
    }
    let warnings = repaired
        .into_iter()
        .map(|id| {
            let material = &materials[id];
            let kd = material.diffuse.unwrap_or_default();
            format!(
                "material {:?}: Kd {} is outside [0, 1] or not finite; baked as {}",
                material.name,
                triple(kd),
                triple(albedo_from_kd(kd).to_array())
            )
        })
        .collect();
    (scene, warnings)
}

/// Kd as albedo: clamped to [0, 1], because albedo above 1 would create energy in the bounce
/// passes, and a NaN taken as 0 (no light reflected), because nothing better can be guessed.
fn albedo_from_kd(kd: [f32; 3]) -> Vec3 {
    Vec3::from_array(kd.map(|c| if c.is_nan() { 0.0 } else { c.clamp(0.0, 1.0) }))
}

fn triple(values: [f32; 3]) -> String {
    format!("({}, {}, {})", values[0], values[1], values[2])
}

fn vec3s(flat: &[f32]) -> impl Iterator<Item = Vec3> + '_ {
    flat.chunks_exact(3).map(Vec3::from_slice)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    /// Writes `text` to `name` in `dir`; returns the path.
    fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
        let path = dir.join(name);
        std::fs::write(&path, text).unwrap();
        path
    }

    /// `usemtl` holds across `o` lines, so the object without a material comes first.
    const THREE_OBJECTS: &str = "mtllib colours.mtl\n\
        v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\n\
        o plain\nf 1 5 6\n\
        o red_quad\nusemtl red\nf 1 2 3 4\n\
        o bright\nusemtl bright\nf 5 6 7\n";

    const MTL: &str = "newmtl red\nKd 0.9 0.1 0.05\n\nnewmtl bright\nKd 2.0 0.5 -1\n";

    #[test]
    fn bunny_counts() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/bunny.obj");
        let scene = load(&path).unwrap();
        assert_eq!(scene.vertex_count(), 1839);
        assert_eq!(scene.triangle_count(), 3674);
        assert_eq!(scene.albedo, vec![DEFAULT_ALBEDO; 1839]);
        assert!(scene.normals.is_none());
    }

    #[test]
    fn objects_are_merged_with_their_material_albedo() {
        let dir = tempfile::tempdir().unwrap();
        write(dir.path(), "colours.mtl", MTL);
        let scene = load(&write(dir.path(), "scene.obj", THREE_OBJECTS)).unwrap();
        // The quad is triangulated; each object has its own vertices.
        assert_eq!(scene.triangle_count(), 4);
        assert_eq!(scene.vertex_count(), 4 + 3 + 3);
        assert_eq!(scene.triangles[0], [0, 1, 2]);
        assert_eq!(scene.triangles[1..3], [[3, 4, 5], [3, 5, 6]]);
        assert_eq!(scene.triangles[3], [7, 8, 9]);
        assert_eq!(scene.albedo[..3], [DEFAULT_ALBEDO; 3]);
        assert_eq!(scene.albedo[3..7], [Vec3::new(0.9, 0.1, 0.05); 4]);
        assert_eq!(scene.albedo[7..], [Vec3::new(1.0, 0.5, 0.0); 3]);
        for t in &scene.triangles {
            let [a, b, c] = t.map(|i| scene.positions[i as usize]);
            assert!((b - a).cross(c - a).length() > 0.0);
        }
    }

    #[test]
    fn missing_mtl_gives_default_albedo() {
        let dir = tempfile::tempdir().unwrap();
        let scene = load(&write(dir.path(), "scene.obj", THREE_OBJECTS)).unwrap();
        assert_eq!(scene.albedo, vec![DEFAULT_ALBEDO; scene.vertex_count()]);
    }

    #[test]
    fn normals_are_kept_only_when_every_object_has_them() {
        let dir = tempfile::tempdir().unwrap();
        let with =
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\no a\nf 1//1 2//1 3//1\no b\nf 3//1 2//1 1//1\n";
        let scene = load(&write(dir.path(), "with.obj", with)).unwrap();
        assert_eq!(scene.normals, Some(vec![Vec3::Z; 6]));
        let mixed = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\no a\nf 1//1 2//1 3//1\no b\nf 3 2 1\n";
        let scene = load(&write(dir.path(), "mixed.obj", mixed)).unwrap();
        assert_eq!(scene.normals, None);
        assert_eq!(scene.vertex_count(), 6);
    }

    #[test]
    fn no_faces_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let path = write(
            dir.path(),
            "lines.obj",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nl 1 2\np 3\n",
        );
        let error = load(&path).unwrap_err();
        assert!(matches!(error, Error::Mesh { .. }));
        assert!(error.to_string().ends_with(": no faces"), "{error}");
    }

    #[test]
    fn out_of_range_kd_is_clamped_with_a_warning_per_material_used() {
        let dir = tempfile::tempdir().unwrap();
        write(dir.path(), "colours.mtl", MTL);
        let (scene, warnings) =
            load_with_warnings(&write(dir.path(), "scene.obj", THREE_OBJECTS)).unwrap();
        assert_eq!(scene.albedo[7..], [Vec3::new(1.0, 0.5, 0.0); 3]);
        assert_eq!(
            warnings,
            [
                "material \"bright\": Kd (2, 0.5, -1) is outside [0, 1] or not finite; baked as \
              (1, 0.5, 0)"
            ]
        );
        // A NaN is taken as 0; a material no face uses says nothing.
        write(
            dir.path(),
            "colours.mtl",
            "newmtl red\nKd 2 nan -1\nnewmtl unused\nKd 9 9 9\n",
        );
        let text = "mtllib colours.mtl\nusemtl red\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
        let (scene, warnings) = load_with_warnings(&write(dir.path(), "nan.obj", text)).unwrap();
        assert_eq!(scene.albedo, [Vec3::X; 3]);
        assert_eq!(warnings.len(), 1, "{warnings:?}");
        assert!(warnings[0].contains("Kd (2, NaN, -1)"), "{warnings:?}");
        assert!(warnings[0].ends_with("baked as (1, 0, 0)"), "{warnings:?}");
    }

    /// `Kd 0.5` is valid MTL (green and blue default to red) and was a panic inside tobj; a
    /// colour with no value at all leaves the library unread, with a warning.
    #[test]
    fn a_colour_of_one_number_is_grey_and_one_of_none_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let obj = "mtllib m.mtl\nusemtl grey\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
        write(dir.path(), "m.mtl", "newmtl grey\nKd 0.5\nKs 0.25 0.5\n");
        let scene = load(&write(dir.path(), "grey.obj", obj)).unwrap();
        assert_eq!(scene.albedo, [Vec3::splat(0.5); 3]);
        write(dir.path(), "m.mtl", "newmtl grey\nKd\n");
        let (scene, warnings) = load_with_warnings(&write(dir.path(), "none.obj", obj)).unwrap();
        assert_eq!(scene.albedo, [DEFAULT_ALBEDO; 3]);
        assert_eq!(warnings.len(), 1, "{warnings:?}");
        assert!(
            warnings[0].contains("material library was not read"),
            "{warnings:?}"
        );
    }

    /// A byte-order mark, comments after statements, CRLF line ends and `\` continuations
    /// (in the OBJ and its MTL) read as the plain file does.
    #[test]
    fn bom_trailing_comments_and_continuations_are_read() {
        let dir = tempfile::tempdir().unwrap();
        write(dir.path(), "colours.mtl", MTL);
        let plain = load(&write(dir.path(), "plain.obj", THREE_OBJECTS)).unwrap();
        let tidy_me = "\u{feff}mtllib colours.mtl # the materials\r\n\
            v 0 0 0 # origin\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\n\
            # a whole-line comment \\\n\
            o plain\nf 1 5 6#not a comment, part of nothing\n\
            o red_quad # a quad\nusemtl red\t# red\nf 1 2 \\\n  3 \\  \r\n4 # continued\n\
            o bright\nusemtl bright\nf 5 6 7\n";
        let tidied = load(&write(dir.path(), "tidy.obj", tidy_me));
        // `6#not` is no comment (no white space before the #), so it is a bad index.
        let error = tidied.unwrap_err().to_string();
        // Line 11: the comment ending in `\` on line 9 continues nothing.
        assert!(error.contains("line 11: \"6#not\""), "{error}");
        let tidy_me = tidy_me.replace("6#not", "6 #not");
        assert_eq!(
            load(&write(dir.path(), "tidy.obj", &tidy_me)).unwrap(),
            plain
        );
        let mtl = format!("\u{feff}{}", MTL.replace("0.05\n", "0.05 # dark red\n"));
        write(dir.path(), "colours.mtl", &mtl);
        assert_eq!(
            load(&write(dir.path(), "tidy.obj", &tidy_me)).unwrap(),
            plain
        );
    }

    #[test]
    fn errors_name_the_line_of_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let head = "# three vertices\nv 0 0 0\nv 1 0 0\nv 0 1 0\n";
        for (body, expected) in [
            (
                "f 1 2 4\n",
                "line 5: vertex index 4 is out of range (the file has 3)",
            ),
            (
                "f 1 \\\n2 \\\n\nf 1 2 0\n",
                "line 8: vertex index 0 (OBJ indices start at 1)",
            ),
            (
                "f -1 -2 -4\n",
                "line 5: vertex index -4 reaches before the first vertex",
            ),
            ("f 1 2 x\n", "line 5: \"x\" is not a vertex reference"),
            (
                "f 1/1/1/1 2 3\n",
                "line 5: \"1/1/1/1\" is not a vertex reference",
            ),
            ("f 1 2 /3\n", "line 5: \"/3\" is not a vertex reference"),
            (
                "vt 0.5\nf 1 2 3\n",
                "line 5: a texture coordinate needs 2 numbers: \"vt 0.5\"",
            ),
            ("vn 0 0 z\n", "line 5: a normal needs 3 numbers"),
            (
                "vt 0 0\nf 1/2 2/1 3/1\n",
                "line 6: texture coordinate index 2 is out of range",
            ),
            (
                "vn 0 0 1\nf 1//1 2//1 3//-2\n",
                "line 6: normal index -2 reaches before",
            ),
        ] {
            let path = write(dir.path(), "bad.obj", &format!("{head}{body}"));
            let error = load(&path).unwrap_err().to_string();
            assert!(
                error.ends_with(&format!("bad.obj: cannot read OBJ: {expected}"))
                    || error.contains(&format!("cannot read OBJ: {expected}")),
                "{body:?}: {error}"
            );
        }
        // What tobj reads, these checks let through: texture and normal indices in a file
        // that has none, a face using a vertex given after it, points and lines.
        let fine = "f 1/7/9 2/7/9 4\nv 0 0 1\nl 1 9\np 12\n";
        assert_eq!(
            load(&write(dir.path(), "ok.obj", &format!("{head}{fine}")))
                .unwrap()
                .triangle_count(),
            1
        );
        let utf16 = [b"\xFF\xFEv".as_slice(), b"\0 \x000\0"].concat();
        std::fs::write(dir.path().join("utf16.obj"), utf16).unwrap();
        let error = load(&dir.path().join("utf16.obj")).unwrap_err().to_string();
        assert!(error.ends_with("UTF-16 text; save it as UTF-8"), "{error}");
    }

    /// A material whose name is empty (Blender's `newmtl ` and `usemtl `, assimp's
    /// empty_mat.obj) is a material like any other: the faces after `usemtl ` take its Kd.
    #[test]
    fn an_empty_material_name_is_a_name() {
        let dir = tempfile::tempdir().unwrap();
        write(
            dir.path(),
            "m.mtl",
            "# Blender MTL\nnewmtl \nNs 0\nKd 0.8 0.6 0.4\nd 1\n",
        );
        let obj = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl \ns off\nf 1 2 3\n";
        let (scene, warnings) = load_with_warnings(&write(dir.path(), "e.obj", obj)).unwrap();
        assert!(warnings.is_empty(), "{warnings:?}");
        assert_eq!(scene.albedo, vec![glam::Vec3::new(0.8, 0.6, 0.4); 3]);
    }

    /// An OBJ and its MTL in Latin-1 (assimp's `regr01.obj` names its materials so) are read,
    /// the names matching as the bytes do, with a warning that names the first line.
    #[test]
    fn latin1_files_are_read_with_a_warning() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(
            dir.path().join("m.mtl"),
            b"newmtl caf\xE9\nKd 0.2 0.4 0.6\n",
        )
        .unwrap();
        let obj = b"mtllib m.mtl\nusemtl caf\xE9\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
        std::fs::write(dir.path().join("latin1.obj"), obj).unwrap();
        let (scene, warnings) = load_with_warnings(&dir.path().join("latin1.obj")).unwrap();
        assert_eq!(scene.albedo, [Vec3::new(0.2, 0.4, 0.6); 3]);
        assert_eq!(
            warnings,
            ["line 2 is not UTF-8 text; the file was read as Latin-1"]
        );
    }

    #[test]
    fn parse_errors_are_one_line_mesh_errors() {
        let dir = tempfile::tempdir().unwrap();
        for text in ["v 0 0 0\nv 1 0 0\nf 1 2 3\n", "v 0 0 zero\nf 1 1 1\n"] {
            let error = load(&write(dir.path(), "bad.obj", text)).unwrap_err();
            assert!(matches!(error, Error::Mesh { .. }), "{error:?}");
            assert!(!error.to_string().contains('\n'));
        }
        let missing = load(&dir.path().join("absent.obj")).unwrap_err();
        assert!(matches!(missing, Error::Io { .. }));
    }
}
