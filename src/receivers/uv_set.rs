//! A lightmap on a scene's own UV set (a glTF scene's `TEXCOORD_1`, laid out by the artist or
//! the engine's unwrapper): the atlas is the set scaled to the map's texels, so the file keeps
//! its vertices and a renderer looks the map up through the coordinates it already has.
//!
//! A set is one a lightmap can use when it lies inside [0, 1] (a lightmap does not tile) and no
//! two triangles cover the same texel centre (each surface point needs texels of its own; a
//! texture set mirrors and repeats, and fails this). Charts are the triangles that share
//! vertices, and so coordinates: texels that a chart with no valid texel would lose are kept
//! (`bake::texels`).

use glam::{DVec2, Vec2};

use super::atlas::{Atlas, MAX_ATLAS_SIZE};
use crate::error::{Error, Result};
use crate::scene::gltf::{self, GltfScene};
use crate::scene::joined::Joined;

/// The set engines put lightmap coordinates in (three.js, Bevy, Unity's UV2, Godot's UV2).
pub const LIGHTMAP_SET: u32 = 1;

/// The UV set a lightmap `size` texels square of the glTF scene `gltf` bakes on (`triangles`
/// being those of the scene `gltf::load` made): the set `named`, else `TEXCOORD_1`, else
/// `TEXCOORD_0` where a lightmap can use it; and a note when it is `TEXCOORD_0`. Refused, with
/// the reason, where none can be used.
pub fn lightmap_set(
    gltf: &GltfScene,
    triangles: &[[u32; 3]],
    named: Option<u32>,
    size: u32,
) -> Result<(UvSet, Option<String>)> {
    let read = |set: u32| -> Result<Option<UvSet>> {
        let uvs = gltf::texcoords(gltf, set).map_err(Error::Geometry)?;
        Ok(uvs.map(|uvs| UvSet::from_vertices(set, &uvs, triangles)))
    };
    let refuse = |why: String| Error::Geometry(format!("--lightmap: {why}"));
    if let Some((mesh, nodes)) = gltf::mesh_placed_twice(gltf) {
        return Err(refuse(format!(
            "mesh {mesh} is shown by {nodes} nodes, whose one UV set would give every placement \
             the same texels, though each sees its own shadows"
        )));
    }
    let usable = |set: UvSet| match set.unusable(size) {
        Some(why) => Err(why),
        None => Ok(set),
    };
    if let Some(named) = named {
        return match read(named)? {
            Some(set) => usable(set).map(|set| (set, None)).map_err(refuse),
            None => Err(refuse(format!(
                "--lightmap-uv {named}: a baked primitive has no TEXCOORD_{named}"
            ))),
        };
    }
    if let Some(set) = read(LIGHTMAP_SET)? {
        return usable(set).map(|set| (set, None)).map_err(refuse);
    }
    let why_not_0 = match read(0)? {
        Some(set) => match usable(set) {
            Ok(set) => {
                let note = "the scene has no TEXCOORD_1; its TEXCOORD_0 does not overlap, and \
                            the lightmap is baked on it";
                return Ok((set, Some(note.into())));
            }
            Err(why) => why,
        },
        None => "no TEXCOORD_0".into(),
    };
    Err(refuse(format!(
        "no usable UV set (no TEXCOORD_1; {why_not_0}), and a scene baked in place keeps its \
         vertices, so it gets no generated atlas: add a second UV set"
    )))
}

/// How far outside [0, 1] a coordinate may lie and still count as inside: rounding of an
/// exporter's quantisation, well under a texel of the largest atlas.
const RANGE_SLACK: f32 = 1e-4;

/// The fraction of covered texel centres that two triangles may both cover before the set
/// counts as overlapping: a few centres on a shared edge are rounding, not overlap.
pub const OVERLAP_FRACTION: f64 = 1e-3;

/// A UV set, per triangle of the scene it was read for.
#[derive(Clone, Debug, PartialEq)]
pub struct UvSet {
    /// The `TEXCOORD_n` it came from.
    pub set: u32,
    /// Per triangle, its corners' coordinates (glTF's convention: v down from the top).
    pub corners: Vec<[Vec2; 3]>,
    /// Per triangle, its chart: triangles sharing a vertex share a chart.
    pub chart_of: Vec<u32>,
}

impl UvSet {
    /// The set `set` whose coordinates per vertex are `uvs`, for `triangles`.
    pub fn from_vertices(set: u32, uvs: &[[f32; 2]], triangles: &[[u32; 3]]) -> UvSet {
        let corners = triangles
            .iter()
            .map(|t| t.map(|i| Vec2::from_array(uvs[i as usize])))
            .collect();
        UvSet {
            set,
            corners,
            chart_of: charts(uvs.len(), triangles),
        }
    }

    /// The set for the triangles `kept` marks (those `prepare` keeps, in order).
    pub fn kept(&self, kept: &[bool]) -> UvSet {
        let pick = |t: &usize| kept.get(*t).copied().unwrap_or(false);
        UvSet {
            set: self.set,
            corners: (0..self.corners.len())
                .filter(pick)
                .map(|t| self.corners[t])
                .collect(),
            chart_of: (0..self.chart_of.len())
                .filter(pick)
                .map(|t| self.chart_of[t])
                .collect(),
        }
    }

    /// Why a lightmap `size` texels square cannot use the set, if it cannot.
    pub fn unusable(&self, size: u32) -> Option<String> {
        let set = self.set;
        let outside = self.corners.iter().enumerate().find_map(|(t, corners)| {
            let inside = |x: f32| (-RANGE_SLACK..=1.0 + RANGE_SLACK).contains(&x);
            corners
                .iter()
                .find(|c| !(inside(c.x) && inside(c.y)))
                .map(|c| (t, *c))
        });
        if let Some((t, c)) = outside {
            return Some(format!(
                "TEXCOORD_{set} leaves [0, 1] (({}, {}) at triangle {t}), so it tiles",
                c.x, c.y
            ));
        }
        let (covered, shared) = overlap(&self.corners, size.min(MAX_ATLAS_SIZE));
        let fraction = shared as f64 / covered.max(1) as f64;
        (fraction > OVERLAP_FRACTION).then(|| {
            format!(
                "TEXCOORD_{set} overlaps itself ({:.1}% of its texels under two triangles)",
                100.0 * fraction
            )
        })
    }

    /// The atlas of a lightmap `size` by `size` texels on this set.
    pub fn atlas(&self, size: u32) -> Atlas {
        let scale = Vec2::splat(size as f32);
        Atlas {
            width: size,
            height: size,
            corners: self.corners.iter().map(|c| c.map(|p| p * scale)).collect(),
            chart_of: self.chart_of.clone(),
        }
    }
}

/// Per triangle, the smallest triangle index of its connected component (by shared vertices),
/// renumbered densely in order of first appearance.
fn charts(vertices: usize, triangles: &[[u32; 3]]) -> Vec<u32> {
    let mut sets = Joined::new(vertices);
    for t in triangles {
        sets.join(t[0], t[1]);
        sets.join(t[0], t[2]);
    }
    let mut number = vec![u32::MAX; vertices];
    let mut next = 0;
    triangles
        .iter()
        .map(|t| {
            let r = sets.root(t[0]) as usize;
            if number[r] == u32::MAX {
                number[r] = next;
                next += 1;
            }
            number[r]
        })
        .collect()
}

/// Of the texel centres of a `size`-square map, how many lie inside some triangle of
/// `corners` (unit coordinates), and how many inside two or more (strictly inside each, so a
/// centre on an edge two neighbours share counts once).
///
/// The map is counted a band of rows at a time (at most [`OVERLAP_BAND_BYTES`] of counts), so
/// that a 16384-texel map costs 16 MiB, not the 256 MiB of all its texels at once.
fn overlap(corners: &[[Vec2; 3]], size: u32) -> (usize, usize) {
    overlap_in_bands(corners, size, OVERLAP_BAND_BYTES)
}

/// [`overlap`], holding at most `band_bytes` of counts at once (at least one row).
fn overlap_in_bands(corners: &[[Vec2; 3]], size: u32, band_bytes: usize) -> (usize, usize) {
    let triangles: Vec<TexelTriangle> = corners
        .iter()
        .filter_map(|t| TexelTriangle::new(t, size))
        .collect();
    let width = size as usize;
    let band_rows = (band_bytes / width.max(1)).clamp(1, width.max(1));
    let mut count = vec![0u8; band_rows * width];
    let (mut covered, mut shared) = (0, 0);
    for band_start in (0..width).step_by(band_rows) {
        let band = band_start as i64..(band_start + band_rows).min(width) as i64;
        count.fill(0);
        for triangle in &triangles {
            let first = (*triangle.rows.start()).max(band.start);
            let last = (*triangle.rows.end()).min(band.end - 1);
            let rows = first..=last;
            for y in rows {
                for x in triangle.columns.clone() {
                    if triangle.strictly_inside(x, y) {
                        let at = (y - band.start) as usize * width + x as usize;
                        count[at] = count[at].saturating_add(1);
                    }
                }
            }
        }
        covered += count.iter().filter(|&&n| n > 0).count();
        shared += count.iter().filter(|&&n| n > 1).count();
    }
    (covered, shared)
}

/// The most bytes of texel counts [`overlap`] holds at once.
const OVERLAP_BAND_BYTES: usize = 16 << 20;

/// A triangle in texel units, with the rows and columns of texel centres its bounds hold.
struct TexelTriangle {
    corners: [DVec2; 3],
    area2: f64,
    rows: std::ops::RangeInclusive<i64>,
    columns: std::ops::RangeInclusive<i64>,
}

impl TexelTriangle {
    /// `None` for a triangle of no area.
    fn new(triangle: &[Vec2; 3], size: u32) -> Option<TexelTriangle> {
        let [a, b, c] = triangle.map(|p| p.as_dvec2() * size as f64);
        let area2 = (b - a).perp_dot(c - a);
        if area2 == 0.0 || !area2.is_finite() {
            return None;
        }
        let lo = a.min(b).min(c);
        let hi = a.max(b).max(c);
        let first = |v: f64| (v - 0.5).ceil().max(0.0) as i64;
        let last = |v: f64| ((v - 0.5).floor().min(size as f64 - 1.0)).max(-1.0) as i64;
        Some(TexelTriangle {
            corners: [a, b, c],
            area2,
            rows: first(lo.y)..=last(hi.y),
            columns: first(lo.x)..=last(hi.x),
        })
    }

    /// Whether the centre of texel `(x, y)` lies strictly inside: a centre on an edge belongs
    /// to neither side.
    fn strictly_inside(&self, x: i64, y: i64) -> bool {
        let [a, b, c] = self.corners;
        let p = DVec2::new(x as f64 + 0.5, y as f64 + 0.5);
        [
            (c - b).perp_dot(p - b),
            (a - c).perp_dot(p - c),
            (b - a).perp_dot(p - a),
        ]
        .iter()
        .all(|&w| w / self.area2 > 1e-9)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two quads side by side in the unit square, each of two triangles.
    fn two_quads(second_at: f32) -> (Vec<[f32; 2]>, Vec<[u32; 3]>) {
        let quad = |x0: f32| [[x0, 0.1], [x0 + 0.4, 0.1], [x0 + 0.4, 0.9], [x0, 0.9]];
        let uvs: Vec<[f32; 2]> = quad(0.05).into_iter().chain(quad(second_at)).collect();
        let triangles = vec![[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]];
        (uvs, triangles)
    }

    /// Counted in bands of a few rows or all at once, the same texels are covered and shared.
    #[test]
    fn overlap_counted_in_bands_is_overlap_counted_whole() {
        let mut random = crate::sampling::Pcg32::new(3);
        let mut point = || Vec2::new(random.next_f32(), random.next_f32());
        let corners: Vec<[Vec2; 3]> = (0..40).map(|_| [point(), point(), point()]).collect();
        let size = 97;
        let whole = overlap_in_bands(&corners, size, usize::MAX);
        assert!(whole.1 > 0 && whole.0 > whole.1, "{whole:?}");
        for band_bytes in [1, 97, 5 * 97, 5 * 97 + 13, 96 * 97] {
            assert_eq!(
                overlap_in_bands(&corners, size, band_bytes),
                whole,
                "{band_bytes}"
            );
        }
    }

    #[test]
    fn disjoint_charts_are_usable_and_numbered_by_shared_vertices() {
        let (uvs, triangles) = two_quads(0.55);
        let set = UvSet::from_vertices(1, &uvs, &triangles);
        assert_eq!(set.chart_of, vec![0, 0, 1, 1]);
        assert_eq!(set.unusable(64), None);
        let atlas = set.atlas(64);
        assert_eq!((atlas.width, atlas.height), (64, 64));
        let corner = atlas.corners[0][1];
        assert!(
            corner.distance(Vec2::new(0.45 * 64.0, 0.1 * 64.0)) < 1e-4,
            "{corner}"
        );
    }

    #[test]
    fn overlapping_or_tiling_sets_are_refused_with_their_reason() {
        let (uvs, triangles) = two_quads(0.25);
        let why = UvSet::from_vertices(0, &uvs, &triangles)
            .unusable(64)
            .unwrap();
        assert!(why.contains("TEXCOORD_0 overlaps itself"), "{why}");
        // Half of each quad's texels lie under the other: 0.2 / 0.6 of those covered.
        assert!(why.contains("(33."), "{why}");
        let (mut uvs, triangles) = two_quads(0.55);
        uvs[5][0] = 1.2;
        let why = UvSet::from_vertices(1, &uvs, &triangles)
            .unusable(64)
            .unwrap();
        assert!(why.contains("leaves [0, 1]"), "{why}");
        uvs[5] = [0.5, -0.3];
        let why = UvSet::from_vertices(1, &uvs, &triangles)
            .unusable(64)
            .unwrap();
        assert!(why.contains("leaves [0, 1]"), "{why}");
    }

    #[test]
    fn kept_triangles_keep_their_corners_and_charts() {
        let (uvs, triangles) = two_quads(0.55);
        let set = UvSet::from_vertices(1, &uvs, &triangles).kept(&[true, false, true, true]);
        assert_eq!(set.corners.len(), 3);
        assert_eq!(set.chart_of, vec![0, 1, 1]);
        assert_eq!(set.corners[1][0], Vec2::new(0.55, 0.1));
    }
}
