//! Environment-map parameterizations: which direction each pixel looks along and how much of the
//! sphere it covers. World frame: right-handed, +Y up (glTF). Pixel (x, y) has its origin at the
//! top-left corner of the image, x to the right, y downwards; "centre" means the pixel centre
//! (x + 0.5, y + 0.5).
//!
//! - `latlong` (equirectangular, the Blender/three.js convention carried to Y-up):
//!   `u = (x + 0.5) / W`, `v = (y + 0.5) / H`, azimuth `a = 2 pi (u - 1/2)`, elevation
//!   `e = pi (1/2 - v)`, direction `(cos e cos a, sin e, cos e sin a)`. The image centre looks
//!   along +X, the quarter at u = 1/4 along -Z, u = 3/4 along +Z, the left and right edges along
//!   -X; the top row is +Y, the bottom row -Y. Seen from inside, the image is not mirrored.
//! - `angular` (Debevec's angular light probe, the tutorial's `LightProbeAccess`): with
//!   `p = (2 (x + 0.5) / W - 1, 1 - 2 (y + 0.5) / H)` (right, up) and `r = |p| <= 1`, the angle from
//!   +Z is `pi r`: direction `(p sin(pi r) / r, cos(pi r))`. Centre +Z, rim -Z, image right +X,
//!   image up +Y. (The tutorial's code indexes rows with +Y increasing downwards; files store the
//!   top row first, so here row 0 is the +Y side, as in Debevec's probes.)
//! - `mirror-ball` (orthographic photograph of a mirror sphere, camera on +Z looking along -Z,
//!   +Y up): normal `n = (p, sqrt(1 - r^2))`, direction = the view ray (0, 0, -1) reflected:
//!   `(2 n_z p, 2 n_z^2 - 1)`. Centre +Z (towards the camera), rim -Z, right +X, up +Y.
//! - cube crosses: faces of side `n`, each face texel at face coordinates `(s, t)` in [-1, 1]
//!   (s to the right, t downwards) looks along `centre + s right + t down`. The layout unfolds the
//!   cube around the -Z face, every face seen from inside unmirrored (`right x down = centre`):
//!   `cross-horizontal` (4n x 3n): row 0 `[ . +Y . . ]`, row 1 `[ -X -Z +X +Z ]`, row 2
//!   `[ . -Y . . ]`; `cross-vertical` (3n x 4n): rows `[ . +Y . ]`, `[ -X -Z +X ]`, `[ . -Y . ]`,
//!   `[ . +Z . ]` with +Z upside down (right +X, down +Y). See [`CROSS_HORIZONTAL`].
//!
//! Solid angles are exact: lat-long and cube texels in closed form, mirror ball as 4 x the exact
//! area of pixel ∩ disc (its Jacobian is the constant 4). The angular map's Jacobian
//! `pi sin(pi r) / r` has no closed-form integral over a square, so it is integrated: 2 x 2
//! Gauss–Legendre per pixel, and near the rim a quadtree split into quadrants (at least 2 levels,
//! 6 levels across the rim, centre-point on the finest cells); the sphere adds up to 4 pi within
//! 6e-8 at 64 x 64. Projection uses the same per-pixel nodes (`pixel_nodes`).

use glam::DVec3;
use std::f64::consts::PI;

/// How the pixels of an environment map are laid out on the sphere.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Mapping {
    /// Equirectangular, 2:1.
    Latlong,
    /// Debevec's angular light probe, 1:1.
    Angular,
    /// Photograph of a mirror ball, 1:1.
    MirrorBall,
    /// Cube cross, four faces wide and three high (4:3).
    CrossHorizontal,
    /// Cube cross, three faces wide and four high (3:4).
    CrossVertical,
}

impl Mapping {
    /// The name used on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Mapping::Latlong => "latlong",
            Mapping::Angular => "angular",
            Mapping::MirrorBall => "mirror-ball",
            Mapping::CrossHorizontal => "cross-horizontal",
            Mapping::CrossVertical => "cross-vertical",
        }
    }

    /// The mapping implied by the aspect ratio, where only one mapping fits it.
    pub fn detect(width: usize, height: usize) -> Result<Mapping, String> {
        check_nonempty(width, height)?;
        let candidates = [
            Mapping::Latlong,
            Mapping::CrossHorizontal,
            Mapping::CrossVertical,
        ];
        if width == height {
            return Err(format!(
                "a square {width}x{height} map is either an angular probe or a mirror ball: \
                 pass --mapping angular or --mapping mirror-ball"
            ));
        }
        candidates
            .into_iter()
            .find(|m| m.check_size(width, height).is_ok())
            .ok_or_else(|| {
                format!(
                    "cannot tell the mapping of a {width}x{height} map from its aspect ratio \
                     (2:1 latlong, 4:3 cross-horizontal, 3:4 cross-vertical, 1:1 angular or \
                     mirror-ball): pass --mapping"
                )
            })
    }

    /// Whether a `width` x `height` image can hold this mapping.
    pub fn check_size(self, width: usize, height: usize) -> Result<(), String> {
        check_nonempty(width, height)?;
        let (fits, wanted) = match self {
            Mapping::Latlong => (width == 2 * height, "2:1 (width = 2 x height)"),
            Mapping::Angular | Mapping::MirrorBall => (width == height, "1:1 (square)"),
            Mapping::CrossHorizontal => (
                width.is_multiple_of(4) && width / 4 * 3 == height,
                "4:3 with a width divisible by 4",
            ),
            Mapping::CrossVertical => (
                width.is_multiple_of(3) && width / 3 * 4 == height,
                "3:4 with a width divisible by 3",
            ),
        };
        if fits {
            Ok(())
        } else {
            Err(format!(
                "a {width}x{height} image cannot be a {} map, which must be {wanted}",
                self.name()
            ))
        }
    }

    /// The given mapping, checked against the size, or the detected one.
    pub fn resolve(
        forced: Option<Mapping>,
        width: usize,
        height: usize,
    ) -> Result<Mapping, String> {
        match forced {
            Some(m) => m.check_size(width, height).map(|()| m),
            None => Mapping::detect(width, height),
        }
    }
}

fn check_nonempty(width: usize, height: usize) -> Result<(), String> {
    if width == 0 || height == 0 {
        Err(format!("the image is empty ({width}x{height})"))
    } else {
        Ok(())
    }
}

/// One face of a cube cross: its cell in the cross (column, row, in face units) and the world
/// directions of the face centre, of increasing x and of increasing y in the image.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CrossFace {
    pub col: usize,
    pub row: usize,
    pub centre: DVec3,
    pub right: DVec3,
    pub down: DVec3,
}

const fn face(col: usize, row: usize, centre: DVec3, right: DVec3, down: DVec3) -> CrossFace {
    CrossFace {
        col,
        row,
        centre,
        right,
        down,
    }
}

/// Faces of the horizontal cross in the order +X, -X, +Y, -Y, +Z, -Z (also the order and
/// orientation of the six separate faces taken by `cross_from_faces`).
pub const CROSS_HORIZONTAL: [CrossFace; 6] = [
    face(2, 1, DVec3::X, DVec3::Z, DVec3::NEG_Y),
    face(0, 1, DVec3::NEG_X, DVec3::NEG_Z, DVec3::NEG_Y),
    face(1, 0, DVec3::Y, DVec3::X, DVec3::NEG_Z),
    face(1, 2, DVec3::NEG_Y, DVec3::X, DVec3::Z),
    face(3, 1, DVec3::Z, DVec3::NEG_X, DVec3::NEG_Y),
    face(1, 1, DVec3::NEG_Z, DVec3::X, DVec3::NEG_Y),
];

/// Faces of the vertical cross, same order; +Z hangs below -Y, upside down.
pub const CROSS_VERTICAL: [CrossFace; 6] = [
    face(2, 1, DVec3::X, DVec3::Z, DVec3::NEG_Y),
    face(0, 1, DVec3::NEG_X, DVec3::NEG_Z, DVec3::NEG_Y),
    face(1, 0, DVec3::Y, DVec3::X, DVec3::NEG_Z),
    face(1, 2, DVec3::NEG_Y, DVec3::X, DVec3::Z),
    face(1, 3, DVec3::Z, DVec3::X, DVec3::Y),
    face(1, 1, DVec3::NEG_Z, DVec3::X, DVec3::NEG_Y),
];

/// Where a pixel of a cross falls: its face and face coordinates of its corners.
struct Texel {
    face: CrossFace,
    /// s0, t0, s1, t1 in [-1, 1].
    bounds: [f64; 4],
}

fn cross_texel(mapping: Mapping, width: usize, x: usize, y: usize) -> Option<Texel> {
    let (faces, per_row) = match mapping {
        Mapping::CrossHorizontal => (&CROSS_HORIZONTAL, 4),
        Mapping::CrossVertical => (&CROSS_VERTICAL, 3),
        _ => return None,
    };
    let n = width / per_row;
    let face = *faces.iter().find(|f| f.col == x / n && f.row == y / n)?;
    let h = 2.0 / n as f64;
    let (i, j) = ((x % n) as f64, (y % n) as f64);
    Some(Texel {
        face,
        bounds: [
            i * h - 1.0,
            j * h - 1.0,
            (i + 1.0) * h - 1.0,
            (j + 1.0) * h - 1.0,
        ],
    })
}

fn face_direction(face: &CrossFace, s: f64, t: f64) -> DVec3 {
    (face.centre + s * face.right + t * face.down).normalize()
}

/// Solid angle of the face rectangle [0, s] x [0, t] (signed): `atan2(s t, sqrt(s^2 + t^2 + 1))`.
fn face_corner_term(s: f64, t: f64) -> f64 {
    (s * t).atan2((s * s + t * t + 1.0).sqrt())
}

fn texel_solid_angle(b: [f64; 4]) -> f64 {
    let [s0, t0, s1, t1] = b;
    face_corner_term(s1, t1) - face_corner_term(s0, t1) - face_corner_term(s1, t0)
        + face_corner_term(s0, t0)
}

/// Lat-long pixel centre direction.
fn latlong_direction(width: usize, height: usize, x: usize, y: usize) -> DVec3 {
    let azimuth = 2.0 * PI * (x as f64 + 0.5) / width as f64 - PI;
    let elevation = 0.5 * PI - PI * (y as f64 + 0.5) / height as f64;
    elevation_azimuth(
        elevation.sin(),
        elevation.cos(),
        azimuth.cos(),
        azimuth.sin(),
    )
}

/// Where a lat-long image of `width x height` looks along `direction`: the continuous position
/// (x, y) in pixels from the top-left corner, the inverse of the pixel-centre directions above
/// (pixel (x, y) looks along `direction` at position (x + 0.5, y + 0.5)). x lies in [0, width],
/// wrapping around; y in [0, height].
pub fn latlong_position(width: usize, height: usize, direction: DVec3) -> (f64, f64) {
    let d = direction.normalize();
    let azimuth = d.z.atan2(d.x);
    let elevation = d.y.clamp(-1.0, 1.0).asin();
    (
        (azimuth + PI) / (2.0 * PI) * width as f64,
        (0.5 - elevation / PI) * height as f64,
    )
}

fn elevation_azimuth(sin_e: f64, cos_e: f64, cos_a: f64, sin_a: f64) -> DVec3 {
    DVec3::new(cos_e * cos_a, sin_e, cos_e * sin_a)
}

/// `2 pi / W (sin e_top - sin e_bottom)`, written with the polar angle from +Y.
fn latlong_solid_angle(width: usize, height: usize, y: usize) -> f64 {
    let polar = |row: usize| PI * row as f64 / height as f64;
    2.0 * PI / width as f64 * (polar(y).cos() - polar(y + 1).cos())
}

/// Disc coordinates (right, up) of an image point given in pixels.
fn disc_point(width: usize, height: usize, px: f64, py: f64) -> (f64, f64) {
    (
        2.0 * px / width as f64 - 1.0,
        1.0 - 2.0 * py / height as f64,
    )
}

fn disc_direction(mapping: Mapping, u: f64, v: f64) -> DVec3 {
    let r = (u * u + v * v).sqrt().min(1.0);
    match mapping {
        Mapping::MirrorBall => {
            let nz = (1.0 - r * r).max(0.0).sqrt();
            DVec3::new(2.0 * nz * u, 2.0 * nz * v, 2.0 * nz * nz - 1.0).normalize()
        }
        _ => {
            if r == 0.0 {
                return DVec3::Z;
            }
            let (sin, cos) = (PI * r).sin_cos();
            let rho = (u * u + v * v).sqrt();
            DVec3::new(u / rho * sin, v / rho * sin, cos)
        }
    }
}

/// `d omega / d area` of the disc mappings in disc coordinates.
fn disc_jacobian(mapping: Mapping, r: f64) -> f64 {
    match mapping {
        Mapping::MirrorBall => 4.0,
        _ if r < 1e-12 => PI * PI,
        _ => PI * (PI * r).sin() / r,
    }
}

/// Area of { (u, v) : 0 <= u <= a, 0 <= v <= b, u^2 + v^2 <= 1 } for a, b >= 0.
fn quadrant_disc_area(a: f64, b: f64) -> f64 {
    let (a, b) = (a.min(1.0), b.min(1.0));
    let knee = (1.0 - b * b).sqrt();
    if a <= knee {
        return a * b;
    }
    // Below v = b up to u = knee, then under the circle from knee to a.
    let primitive = |u: f64| 0.5 * (u * (1.0 - u * u).max(0.0).sqrt() + u.asin());
    knee * b + primitive(a) - primitive(knee)
}

/// Signed extension of `quadrant_disc_area` to the whole plane (odd in each argument).
fn signed_disc_area(a: f64, b: f64) -> f64 {
    a.signum() * b.signum() * quadrant_disc_area(a.abs(), b.abs())
}

/// Exact area of the rectangle [u0, u1] x [v0, v1] inside the unit disc.
fn rect_disc_area(u0: f64, v0: f64, u1: f64, v1: f64) -> f64 {
    // The signed sum cancels to rounding noise for rectangles outside the disc: call them empty.
    if nearest_point([u0, v0, u1, v1]) >= 1.0 {
        return 0.0;
    }
    (signed_disc_area(u1, v1) - signed_disc_area(u0, v1) - signed_disc_area(u1, v0)
        + signed_disc_area(u0, v0))
    .max(0.0)
}

/// The disc-coordinate rectangle of a pixel: (u0, v0, u1, v1) with u0 < u1, v0 < v1.
fn disc_pixel_rect(width: usize, height: usize, x: usize, y: usize) -> [f64; 4] {
    let (u0, v1) = disc_point(width, height, x as f64, y as f64);
    let (u1, v0) = disc_point(width, height, x as f64 + 1.0, y as f64 + 1.0);
    [u0, v0, u1, v1]
}

fn farthest_corner(rect: [f64; 4]) -> f64 {
    let [u0, v0, u1, v1] = rect;
    let (u, v) = (u0.abs().max(u1.abs()), v0.abs().max(v1.abs()));
    (u * u + v * v).sqrt()
}

fn nearest_point(rect: [f64; 4]) -> f64 {
    let [u0, v0, u1, v1] = rect;
    let clamp = |lo: f64, hi: f64| {
        if lo > 0.0 {
            lo
        } else if hi < 0.0 {
            -hi
        } else {
            0.0
        }
    };
    let (u, v) = (clamp(u0, u1), clamp(v0, v1));
    (u * u + v * v).sqrt()
}

/// Direction of the centre of pixel (x, y), or `None` if the pixel covers no part of the sphere
/// (outside the disc or the cross). For a disc pixel straddling the rim whose centre lies outside,
/// the centre is pulled onto the rim, which is -Z.
pub fn pixel_direction(
    mapping: Mapping,
    width: usize,
    height: usize,
    x: usize,
    y: usize,
) -> Option<DVec3> {
    if x >= width || y >= height {
        return None;
    }
    match mapping {
        Mapping::Latlong => Some(latlong_direction(width, height, x, y)),
        Mapping::Angular | Mapping::MirrorBall => {
            if nearest_point(disc_pixel_rect(width, height, x, y)) >= 1.0 {
                return None;
            }
            let (u, v) = disc_point(width, height, x as f64 + 0.5, y as f64 + 0.5);
            Some(disc_direction(mapping, u, v))
        }
        Mapping::CrossHorizontal | Mapping::CrossVertical => {
            let texel = cross_texel(mapping, width, x, y)?;
            let [s0, t0, s1, t1] = texel.bounds;
            Some(face_direction(
                &texel.face,
                0.5 * (s0 + s1),
                0.5 * (t0 + t1),
            ))
        }
    }
}

/// Solid angle covered by pixel (x, y); zero outside the disc or the cross.
pub fn pixel_solid_angle(mapping: Mapping, width: usize, height: usize, x: usize, y: usize) -> f64 {
    if x >= width || y >= height {
        return 0.0;
    }
    match mapping {
        Mapping::Latlong => latlong_solid_angle(width, height, y),
        Mapping::MirrorBall => {
            let [u0, v0, u1, v1] = disc_pixel_rect(width, height, x, y);
            4.0 * rect_disc_area(u0, v0, u1, v1)
        }
        Mapping::Angular => {
            let mut nodes = Vec::new();
            disc_nodes(mapping, width, height, x, y, &mut nodes);
            nodes.iter().map(|(_, w)| w).sum()
        }
        Mapping::CrossHorizontal | Mapping::CrossVertical => cross_texel(mapping, width, x, y)
            .map(|t| texel_solid_angle(t.bounds))
            .unwrap_or(0.0),
    }
}

/// Gauss–Legendre 2-point abscissae on [-1, 1] (weights 1).
const GL2: [f64; 2] = [-0.577_350_269_189_625_8, 0.577_350_269_189_625_8];

/// Disc pixels whose farthest corner lies beyond `1 - RIM_BAND_PIXELS * pixel size` are split
/// into quadrants, because the mirror ball's map is singular at the rim and the disc edge cuts
/// through pixels there.
const RIM_BAND_PIXELS: f64 = 2.0;

/// Quadrants inside the disc but near the rim are split at least this often...
const RIM_MIN_DEPTH: u32 = 2;

/// ...and quadrants across the rim this often, then sampled at their centre if inside.
const RIM_MAX_DEPTH: u32 = 6;

/// Quadrature nodes (direction, weight) of a pixel: `sum w f(dir)` approximates the integral of
/// `f` over the part of the sphere the pixel covers, and the weights add up to the pixel's
/// solid angle (exactly where a closed form exists). Using nodes rather than only the pixel
/// centre makes a constant map project to the DC term alone to ~1e-10 rather than ~1e-6.
pub(crate) fn pixel_nodes(layout: &Layout, x: usize, y: usize, out: &mut Vec<(DVec3, f64)>) {
    out.clear();
    let (mapping, width, height) = (layout.mapping, layout.width, layout.height);
    match mapping {
        Mapping::Latlong => {
            let (cos_a, sin_a) = layout.columns[x];
            for &(sin_e, cos_e, w) in &layout.rows[y] {
                out.push((elevation_azimuth(sin_e, cos_e, cos_a, sin_a), w));
            }
        }
        Mapping::Angular | Mapping::MirrorBall => disc_nodes(mapping, width, height, x, y, out),
        Mapping::CrossHorizontal | Mapping::CrossVertical => {
            let Some(texel) = cross_texel(mapping, width, x, y) else {
                return;
            };
            let [s0, t0, s1, t1] = texel.bounds;
            let (sc, tc, half) = (0.5 * (s0 + s1), 0.5 * (t0 + t1), 0.5 * (s1 - s0));
            for gt in GL2 {
                for gs in GL2 {
                    let (s, t) = (sc + half * gs, tc + half * gt);
                    let jacobian = (1.0 + s * s + t * t).powf(-1.5);
                    out.push((face_direction(&texel.face, s, t), jacobian));
                }
            }
            normalize_weights(out, texel_solid_angle(texel.bounds));
        }
    }
}

fn normalize_weights(nodes: &mut [(DVec3, f64)], total: f64) {
    let sum: f64 = nodes.iter().map(|(_, w)| w).sum();
    if sum > 0.0 {
        for (_, w) in nodes.iter_mut() {
            *w *= total / sum;
        }
    }
}

fn disc_nodes(
    mapping: Mapping,
    width: usize,
    height: usize,
    x: usize,
    y: usize,
    out: &mut Vec<(DVec3, f64)>,
) {
    out.clear();
    let rect = disc_pixel_rect(width, height, x, y);
    if nearest_point(rect) >= 1.0 {
        return;
    }
    let pixel_size = rect[2] - rect[0];
    disc_cell(mapping, rect, pixel_size, 0, out);
    if mapping == Mapping::MirrorBall {
        let [u0, v0, u1, v1] = rect;
        let exact = 4.0 * rect_disc_area(u0, v0, u1, v1);
        if out.is_empty() && exact > 0.0 {
            // A sliver of the rim missed by every sub-cell: the whole rim looks along -Z.
            out.push((DVec3::NEG_Z, exact));
        }
        normalize_weights(out, exact);
    }
}

/// Quadrature nodes of one disc-coordinate rectangle, split into quadrants near the rim:
/// 2 x 2 Gauss–Legendre where the map is smooth, the centre point on the finest cells that
/// the rim cuts.
fn disc_cell(
    mapping: Mapping,
    rect: [f64; 4],
    pixel_size: f64,
    depth: u32,
    out: &mut Vec<(DVec3, f64)>,
) {
    if nearest_point(rect) >= 1.0 {
        return;
    }
    let [u0, v0, u1, v1] = rect;
    let far = farthest_corner(rect);
    let near_rim = far > 1.0 - RIM_BAND_PIXELS * pixel_size;
    if !near_rim || (far <= 1.0 && depth >= RIM_MIN_DEPTH) {
        let (du, dv) = (u1 - u0, v1 - v0);
        for gv in GL2 {
            for gu in GL2 {
                let u = u0 + 0.5 * du * (1.0 + gu);
                let v = v0 + 0.5 * dv * (1.0 + gv);
                let r = (u * u + v * v).sqrt();
                out.push((
                    disc_direction(mapping, u, v),
                    disc_jacobian(mapping, r) * 0.25 * du * dv,
                ));
            }
        }
        return;
    }
    let (um, vm) = (0.5 * (u0 + u1), 0.5 * (v0 + v1));
    if depth >= RIM_MAX_DEPTH {
        let r = (um * um + vm * vm).sqrt();
        if r <= 1.0 {
            out.push((
                disc_direction(mapping, um, vm),
                disc_jacobian(mapping, r) * (u1 - u0) * (v1 - v0),
            ));
        }
        return;
    }
    for quadrant in [
        [u0, v0, um, vm],
        [um, v0, u1, vm],
        [u0, vm, um, v1],
        [um, vm, u1, v1],
    ] {
        disc_cell(mapping, quadrant, pixel_size, depth + 1, out);
    }
}

/// Per-image tables that make `pixel_nodes` cheap: for lat-long, the azimuth of every column
/// and two Gauss–Legendre elevation nodes per row, so no pixel needs trigonometry.
pub(crate) struct Layout {
    mapping: Mapping,
    width: usize,
    height: usize,
    /// Lat-long: (cos a, sin a) per column.
    columns: Vec<(f64, f64)>,
    /// Lat-long: (sin e, cos e, weight) per row node; weights add up to the pixel's solid angle.
    rows: Vec<[(f64, f64, f64); 2]>,
}

impl Layout {
    pub(crate) fn new(mapping: Mapping, width: usize, height: usize) -> Self {
        let (columns, rows) = if mapping == Mapping::Latlong {
            let columns = (0..width)
                .map(|x| {
                    let a = 2.0 * PI * (x as f64 + 0.5) / width as f64 - PI;
                    (a.cos(), a.sin())
                })
                .collect();
            let rows = (0..height)
                .map(|y| latlong_row_nodes(width, height, y))
                .collect();
            (columns, rows)
        } else {
            (Vec::new(), Vec::new())
        };
        Layout {
            mapping,
            width,
            height,
            columns,
            rows,
        }
    }
}

/// Two Gauss–Legendre nodes in the polar angle (from +Y) of row y, weighted by sin(polar) and
/// scaled to the row pixel's exact solid angle. Along a row, one node per pixel centre is
/// already exact for whole rings: equally spaced samples integrate trigonometric polynomials
/// of degree below W exactly, and every SH function restricted to a ring is one.
pub(crate) fn latlong_row_nodes(width: usize, height: usize, y: usize) -> [(f64, f64, f64); 2] {
    let step = PI / height as f64;
    let mid = (y as f64 + 0.5) * step;
    let node = |g: f64| {
        let polar = mid + 0.5 * step * g;
        let (sin_p, cos_p) = polar.sin_cos();
        // Elevation e = pi/2 - polar: sin e = cos polar, cos e = sin polar.
        (cos_p, sin_p, sin_p)
    };
    let nodes = [node(GL2[0]), node(GL2[1])];
    let total = latlong_solid_angle(width, height, y);
    let sum = nodes[0].2 + nodes[1].2;
    nodes.map(|(s, c, w)| (s, c, w * total / sum))
}

/// Every parameterization and a size of the right aspect, for tests across mappings.
#[cfg(test)]
pub(crate) mod test_support {
    use super::Mapping;

    pub(crate) const ALL: [Mapping; 5] = [
        Mapping::Latlong,
        Mapping::Angular,
        Mapping::MirrorBall,
        Mapping::CrossHorizontal,
        Mapping::CrossVertical,
    ];

    pub(crate) fn size_for(mapping: Mapping, n: usize) -> (usize, usize) {
        match mapping {
            Mapping::Latlong => (2 * n, n),
            Mapping::Angular | Mapping::MirrorBall => (n, n),
            Mapping::CrossHorizontal => (4 * n, 3 * n),
            Mapping::CrossVertical => (3 * n, 4 * n),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::test_support::{size_for, ALL};
    use super::*;

    fn close(a: DVec3, b: DVec3, tol: f64) -> bool {
        (a - b).length() < tol
    }

    #[test]
    fn solid_angles_add_up_to_the_sphere() {
        for mapping in ALL {
            let (w, h) = size_for(mapping, 64);
            let total: f64 = (0..h)
                .flat_map(|y| (0..w).map(move |x| (x, y)))
                .map(|(x, y)| pixel_solid_angle(mapping, w, h, x, y))
                .sum();
            eprintln!(
                "{mapping:?}: solid angles / 4 pi - 1 = {:e}",
                total / (4.0 * PI) - 1.0
            );
            // Angular has no closed form: its Jacobian is integrated numerically.
            let tol = if mapping == Mapping::Angular {
                1e-7
            } else {
                1e-12
            };
            assert!(
                (total - 4.0 * PI).abs() < tol * 4.0 * PI,
                "{mapping:?}: {total}"
            );
        }
    }

    #[test]
    fn node_weights_match_the_solid_angle_and_centre() {
        for mapping in ALL {
            let (w, h) = size_for(mapping, 32);
            let layout = Layout::new(mapping, w, h);
            let mut nodes = Vec::new();
            for y in 0..h {
                for x in 0..w {
                    pixel_nodes(&layout, x, y, &mut nodes);
                    let sum: f64 = nodes.iter().map(|(_, w)| w).sum();
                    let omega = pixel_solid_angle(mapping, w, h, x, y);
                    assert!((sum - omega).abs() <= 1e-12 * omega.max(1e-300) + 1e-15);
                    // A disc pixel may graze the rim with a sliver no node lands in.
                    let has_direction = pixel_direction(mapping, w, h, x, y).is_some();
                    assert!(has_direction || omega == 0.0, "{mapping:?} {x} {y}");
                    if omega > 0.0 && mapping != Mapping::MirrorBall {
                        let mean = nodes.iter().map(|(d, w)| *d * *w).sum::<DVec3>() / sum;
                        let centre = pixel_direction(mapping, w, h, x, y).unwrap();
                        assert!(close(mean.normalize(), centre, 0.1), "{mapping:?} {x} {y}");
                    }
                }
            }
        }
    }

    #[test]
    fn named_pixels_look_where_documented() {
        let (w, h) = (1024, 512);
        let d = |x, y| pixel_direction(Mapping::Latlong, w, h, x, y).unwrap();
        let tol = 0.01;
        // Centre pixel: +X; quarter: -Z; three quarters: +Z; left edge: -X; rows: +Y top.
        assert!(close(d(512, 256), DVec3::X, tol));
        assert!(close(d(256, 256), DVec3::NEG_Z, tol));
        assert!(close(d(768, 256), DVec3::Z, tol));
        assert!(close(d(0, 256), DVec3::NEG_X, tol));
        assert!(d(300, 0).y > 0.9999 && d(300, 511).y < -0.9999);

        for mapping in [Mapping::Angular, Mapping::MirrorBall] {
            let d = |x, y| pixel_direction(mapping, 512, 512, x, y).unwrap();
            assert!(close(d(256, 256), DVec3::Z, tol), "{mapping:?} centre");
            // Right of centre leans +X, above centre leans +Y; the rim looks back along -Z.
            assert!(d(400, 256).x > 0.5 && d(256, 100).y > 0.5, "{mapping:?}");
            assert!(d(511, 256).z < -0.99, "{mapping:?} rim");
            assert!(pixel_direction(mapping, 512, 512, 0, 0).is_none());
        }
        // Angular: halfway to the rim is 90 degrees from +Z.
        let half = pixel_direction(Mapping::Angular, 512, 512, 384, 256).unwrap();
        assert!(half.z.abs() < 0.01 && half.x > 0.99);
        // Mirror ball: halfway to the rim reflects 60 degrees away (r = sin(theta / 2)).
        let half = pixel_direction(Mapping::MirrorBall, 512, 512, 384, 256).unwrap();
        assert!((half.z - 0.5).abs() < 0.01);

        for (mapping, n) in [(Mapping::CrossHorizontal, 4), (Mapping::CrossVertical, 3)] {
            let faces = if n == 4 {
                &CROSS_HORIZONTAL
            } else {
                &CROSS_VERTICAL
            };
            let size = 16;
            let (w, h) = (n * size, (12 / n) * size);
            for f in faces {
                // The texel right of and below the face centre.
                let (x, y) = (f.col * size + size / 2, f.row * size + size / 2);
                let d = pixel_direction(mapping, w, h, x, y).unwrap();
                let expected = (f.centre + (f.right + f.down) / size as f64).normalize();
                assert!(close(d, expected, 1e-12), "{mapping:?} {:?}", f.centre);
                assert!(close(f.right.cross(f.down), f.centre, 1e-12));
            }
            assert!(pixel_direction(mapping, w, h, 0, 0).is_none());
            assert_eq!(pixel_solid_angle(mapping, w, h, 0, 0), 0.0);
        }
        // Faces meet edge to edge: the texels either side of the -Z / +X seam are neighbours.
        let (w, h) = (64, 48);
        let a = pixel_direction(Mapping::CrossHorizontal, w, h, 31, 24).unwrap();
        let b = pixel_direction(Mapping::CrossHorizontal, w, h, 32, 24).unwrap();
        assert!(a.angle_between(b) < 0.15 && a.z < 0.0 && b.x > 0.0);
        // Vertical cross: bottom of -Y continues into the top of the upside-down +Z.
        let (w, h) = (48, 64);
        let a = pixel_direction(Mapping::CrossVertical, w, h, 24, 47).unwrap();
        let b = pixel_direction(Mapping::CrossVertical, w, h, 24, 48).unwrap();
        assert!(a.angle_between(b) < 0.15, "{a} {b}");
        assert!(
            a.y < -0.6 && a.z > 0.6 && b.y < -0.6 && b.z > 0.6,
            "{a} {b}"
        );
    }

    #[test]
    fn aspect_detection_and_checks() {
        assert_eq!(Mapping::detect(1024, 512), Ok(Mapping::Latlong));
        assert_eq!(Mapping::detect(1024, 768), Ok(Mapping::CrossHorizontal));
        assert_eq!(Mapping::detect(768, 1024), Ok(Mapping::CrossVertical));
        let square = Mapping::detect(512, 512).unwrap_err();
        assert!(square.contains("--mapping angular") && square.contains("mirror-ball"));
        assert!(Mapping::detect(1000, 300).is_err());
        assert!(Mapping::detect(0, 0).unwrap_err().contains("empty"));
        let wrong = Mapping::resolve(Some(Mapping::Angular), 1024, 512).unwrap_err();
        assert!(
            wrong.contains("1024x512") && wrong.contains("angular"),
            "{wrong}"
        );
        assert!(Mapping::CrossHorizontal.check_size(1022, 766).is_err());
        assert_eq!(
            Mapping::resolve(Some(Mapping::MirrorBall), 64, 64),
            Ok(Mapping::MirrorBall)
        );
    }

    #[test]
    fn disc_area_is_exact() {
        assert!((rect_disc_area(-1.0, -1.0, 1.0, 1.0) - PI).abs() < 1e-14);
        assert!((rect_disc_area(0.0, 0.0, 1.0, 1.0) - PI / 4.0).abs() < 1e-14);
        assert!((rect_disc_area(-0.5, -0.5, 0.5, 0.5) - 1.0).abs() < 1e-14);
        // Upper half beyond v = 0.5: a circular segment, (pi/3 - sqrt(3)/4) by geometry.
        let segment = PI / 3.0 - 3f64.sqrt() / 4.0;
        assert!((rect_disc_area(-1.0, 0.5, 1.0, 1.0) - segment).abs() < 1e-14);
    }
}
