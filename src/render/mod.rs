//! Relighting and preview images: the run-time half of PRT.
//!
//! `relight` turns a baked [`Transfer`] and an [`ShLight`] into per-vertex exit radiance (one
//! dot product per vertex and channel); `render` rasterises the mesh with that radiance
//! interpolated across triangles into a linear HDR image on any wgpu adapter (lavapipe
//! included); `write_image` stores it as a tone-mapped 8-bit sRGB PNG or as a linear `.exr`.

use std::io::Cursor;
use std::path::Path;
use std::str::FromStr;

use glam::{Mat4, Vec3};
use rayon::prelude::*;
use wgpu::util::DeviceExt;

use crate::bake::Transfer;
use crate::color::srgb_encode;
use crate::device::GpuContext;
use crate::error::{Error, Result};
use crate::fs::{format_by_extension, write_atomically};
use crate::light::ShLight;
use crate::scene::Scene;
use crate::shaders;

/// Per-vertex exit radiance `L_o[c] = sum_k light[k][c] * transfer[v][c][k]`, linear RGB.
///
/// Bands: only the coefficients both sides have are summed. A light with more bands than the
/// transfer is truncated (the transfer has no response to the higher bands); a light with
/// fewer bands is treated as zero-padded, which is exact for a band-limited light.
/// A one-channel transfer applies to all three light channels.
pub fn relight(transfer: &Transfer, light: &ShLight) -> Result<Vec<[f32; 3]>> {
    check_transfer(transfer)?;
    check_light(light)?;
    let per_channel = transfer.coeffs_per_channel();
    let channels = transfer.channels as usize;
    let light = &light.coeffs[..per_channel.min(light.coeffs.len())];
    Ok(transfer
        .coeffs
        .par_chunks_exact(per_channel * channels)
        // Vertices are tiny work items; batching keeps rayon's bookkeeping below the work.
        .with_min_len(1024)
        .map(|vertex| vertex_radiance(vertex, per_channel, light))
        .collect())
}

/// One vertex: `vertex` holds its `channels * per_channel` coefficients, channel-major.
fn vertex_radiance(vertex: &[f32], per_channel: usize, light: &[[f32; 3]]) -> [f32; 3] {
    let channels = vertex.len() / per_channel;
    std::array::from_fn(|c| {
        let start = c.min(channels - 1) * per_channel;
        vertex[start..start + light.len()]
            .iter()
            .zip(light)
            .map(|(t, l)| t * l[c])
            .sum()
    })
}

fn check_transfer(transfer: &Transfer) -> Result<()> {
    if transfer.bands == 0 || !matches!(transfer.channels, 1 | 3) {
        return Err(Error::Options(format!(
            "relight: transfer with {} bands and {} channels (need at least 1 band, 1 or 3 channels)",
            transfer.bands, transfer.channels
        )));
    }
    let expected = transfer
        .vertex_count
        .checked_mul(transfer.channels as usize * transfer.coeffs_per_channel());
    if expected != Some(transfer.coeffs.len()) {
        return Err(Error::Options(format!(
            "relight: transfer holds {} coefficients, not vertices x channels x bands^2 = {} x {} x {}",
            transfer.coeffs.len(),
            transfer.vertex_count,
            transfer.channels,
            transfer.coeffs_per_channel()
        )));
    }
    Ok(())
}

fn check_light(light: &ShLight) -> Result<()> {
    let expected = crate::sh::coeff_count(light.bands);
    if light.bands == 0 || light.coeffs.len() != expected {
        return Err(Error::Options(format!(
            "relight: light with {} bands holds {} coefficients (need bands >= 1 and bands^2)",
            light.bands,
            light.coeffs.len()
        )));
    }
    Ok(())
}

/// Vertical field of view of framed and parsed cameras unless one is given.
pub const DEFAULT_FOV_DEG: f32 = 40.0;

/// The framing view direction: from the front (+Z, where glTF models face) and a little to the
/// right and above, the usual three-quarter product shot.
const FRAMING_AZIMUTH_DEG: f32 = 35.0;
const FRAMING_ELEVATION_DEG: f32 = 25.0;
/// Room left around the bounding sphere, so silhouettes do not touch the image border.
const FRAMING_MARGIN: f32 = 1.1;

/// A pinhole camera, right-handed world, looking from `eye` at `target`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub eye: Vec3,
    pub target: Vec3,
    pub up: Vec3,
    pub vertical_fov_deg: f32,
}

impl Camera {
    /// A three-quarter view (Y up) that fits the bounding sphere of the box in a square image
    /// (wider images get more room at the sides), aimed at the box centre.
    pub fn framing(bounds_min: Vec3, bounds_max: Vec3) -> Camera {
        let center = (bounds_min + bounds_max) * 0.5;
        let radius = usable_radius((bounds_max - bounds_min).length() * 0.5, center);
        let half_fov = (DEFAULT_FOV_DEG * 0.5).to_radians();
        let distance = FRAMING_MARGIN * radius / half_fov.sin();
        let (azimuth, elevation) = (
            FRAMING_AZIMUTH_DEG.to_radians(),
            FRAMING_ELEVATION_DEG.to_radians(),
        );
        let direction = Vec3::new(
            elevation.cos() * azimuth.sin(),
            elevation.sin(),
            elevation.cos() * azimuth.cos(),
        );
        Camera {
            eye: center + direction * distance,
            target: center,
            up: Vec3::Y,
            vertical_fov_deg: DEFAULT_FOV_DEG,
        }
    }

    /// Frames every position of `scene` (see [`Camera::framing`]).
    pub fn framing_scene(scene: &Scene) -> Camera {
        let (min, max) = bounds(&scene.positions);
        Camera::framing(min, max)
    }

    /// Refuses cameras that give no image: non-finite values, eye on the target, zero up
    /// vector, field of view outside (0, 180) degrees.
    pub fn validate(&self) -> Result<()> {
        let finite = self.eye.is_finite()
            && self.target.is_finite()
            && self.up.is_finite()
            && self.vertical_fov_deg.is_finite();
        if !finite {
            return Err(Error::Options(format!("camera {self:?} is not finite")));
        }
        if (self.target - self.eye).length_squared() == 0.0 || self.up.length_squared() == 0.0 {
            return Err(Error::Options(
                "camera: eye equals target, or up is zero".to_string(),
            ));
        }
        if !(self.vertical_fov_deg > 0.0 && self.vertical_fov_deg < 180.0) {
            return Err(Error::Options(format!(
                "camera: field of view {} must lie in (0, 180) degrees",
                self.vertical_fov_deg
            )));
        }
        Ok(())
    }

    /// World to clip space for wgpu (WebGPU NDC: Y up, depth 0 at `near`, 1 at `far`).
    pub fn clip_from_world(&self, aspect: f32, near: f32, far: f32) -> Mat4 {
        use glam::camera::rh::{proj::directx, view};
        let projection =
            directx::perspective(self.vertical_fov_deg.to_radians(), aspect, near, far);
        projection * view::look_at_mat4(self.eye, self.target, self.usable_up())
    }

    /// `up` unless it is parallel to the view direction (looking straight down, say), where
    /// look-at would divide by zero; then any perpendicular-enough axis does.
    fn usable_up(&self) -> Vec3 {
        let forward = (self.target - self.eye).normalize();
        [self.up.normalize(), Vec3::Z, Vec3::X]
            .into_iter()
            .find(|up| forward.cross(*up).length() > 1e-3)
            .unwrap_or(Vec3::Y)
    }
}

/// Parses "eye_x,eye_y,eye_z,target_x,target_y,target_z[,fov_deg]" (Y up).
impl FromStr for Camera {
    type Err = Error;

    fn from_str(text: &str) -> Result<Camera> {
        let numbers = text
            .split(',')
            .map(|part| part.trim().parse::<f32>())
            .collect::<std::result::Result<Vec<f32>, _>>()
            .map_err(|e| Error::Options(format!("camera {text:?}: {e}")))?;
        let camera = match numbers[..] {
            [ex, ey, ez, tx, ty, tz] => (ex, ey, ez, tx, ty, tz, DEFAULT_FOV_DEG),
            [ex, ey, ez, tx, ty, tz, fov] => (ex, ey, ez, tx, ty, tz, fov),
            _ => {
                return Err(Error::Options(format!(
                    "camera {text:?}: expected eye_x,eye_y,eye_z,target_x,target_y,target_z[,fov]"
                )))
            }
        };
        let (ex, ey, ez, tx, ty, tz, fov) = camera;
        let camera = Camera {
            eye: Vec3::new(ex, ey, ez),
            target: Vec3::new(tx, ty, tz),
            up: Vec3::Y,
            vertical_fov_deg: fov,
        };
        camera.validate()?;
        Ok(camera)
    }
}

/// A positive radius even for a single point, so framing any finite box gives a camera that
/// `validate` accepts.
fn usable_radius(radius: f32, center: Vec3) -> f32 {
    let floor = 1e-3 * center.abs().max_element().max(1.0);
    if radius.is_finite() {
        radius.max(floor)
    } else {
        1.0
    }
}

/// Axis-aligned bounds of `positions` (an empty slice gives the origin).
pub fn bounds(positions: &[Vec3]) -> (Vec3, Vec3) {
    if positions.is_empty() {
        return (Vec3::ZERO, Vec3::ZERO);
    }
    positions
        .iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(*p), hi.max(*p))
        })
}

/// The preview shader's parameters; mirrored by `RenderParams` in `wgsl/render.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct RenderParams {
    pub clip_from_world: [[f32; 4]; 4],
}

const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// The colour target's texel format.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum ColorFormat {
    /// Keeps the radiance exact; renderable in core WebGPU and on Vulkan (lavapipe included).
    Rgba32Float,
    /// For downlevel backends (wgpu's GL) that cannot render to 32-bit float: 11-bit
    /// mantissa, range to 65504, plenty for a preview.
    Rgba16Float,
}

impl ColorFormat {
    /// The most precise format the adapter can render to and copy out.
    fn for_adapter(ctx: &GpuContext) -> Result<ColorFormat> {
        let needed = wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC;
        [ColorFormat::Rgba32Float, ColorFormat::Rgba16Float]
            .into_iter()
            .find(|f| {
                ctx.format_features(f.texture())
                    .allowed_usages
                    .contains(needed)
            })
            .ok_or_else(|| {
                Error::Gpu(format!(
                    "{}: cannot render to a floating-point colour target",
                    ctx.adapter.name
                ))
            })
    }

    fn texture(self) -> wgpu::TextureFormat {
        match self {
            ColorFormat::Rgba32Float => wgpu::TextureFormat::Rgba32Float,
            ColorFormat::Rgba16Float => wgpu::TextureFormat::Rgba16Float,
        }
    }

    fn bytes_per_pixel(self) -> u32 {
        match self {
            ColorFormat::Rgba32Float => 16,
            ColorFormat::Rgba16Float => 8,
        }
    }

    /// Texels as the GPU wrote them (native byte order) to RGBA f32.
    fn decode(self, bytes: &[u8]) -> impl Iterator<Item = [f32; 4]> + '_ {
        let lanes: Box<dyn Iterator<Item = f32>> = match self {
            ColorFormat::Rgba32Float => Box::new(
                bytes
                    .chunks_exact(4)
                    .map(|b| f32::from_ne_bytes([b[0], b[1], b[2], b[3]])),
            ),
            ColorFormat::Rgba16Float => Box::new(
                bytes
                    .chunks_exact(2)
                    .map(|b| f16_to_f32(u16::from_ne_bytes([b[0], b[1]]))),
            ),
        };
        let mut lanes = lanes.fuse();
        std::iter::from_fn(move || {
            Some([lanes.next()?, lanes.next()?, lanes.next()?, lanes.next()?])
        })
    }
}

/// IEEE binary16 to f32, exact for every input (subnormals, infinities and NaN included).
fn f16_to_f32(bits: u16) -> f32 {
    let sign = if bits & 0x8000 != 0 { -1.0 } else { 1.0 };
    let exponent = i32::from((bits >> 10) & 0x1f);
    let mantissa = f32::from(bits & 0x3ff);
    let magnitude = match exponent {
        0 => mantissa * (-24f32).exp2(),
        31 if mantissa == 0.0 => f32::INFINITY,
        31 => f32::NAN,
        _ => (1.0 + mantissa / 1024.0) * ((exponent - 15) as f32).exp2(),
    };
    sign * magnitude
}

/// A baked mesh relit under `light` and rendered from `camera` (framed automatically when
/// `None`): linear HDR RGBA, row 0 at the top.
pub fn preview(
    ctx: &GpuContext,
    baked: &crate::bake::BakedMesh,
    light: &ShLight,
    camera: Option<&Camera>,
    width: u32,
    height: u32,
) -> Result<Vec<[f32; 4]>> {
    let radiance = relight(&baked.transfer, light)?;
    let framed = Camera::framing_scene(&baked.scene);
    render(
        ctx,
        &baked.scene,
        &radiance,
        camera.unwrap_or(&framed),
        width,
        height,
    )
}

/// Rasterises `scene` with `radiance` (one RGB value per vertex, interpolated across each
/// triangle) seen by `camera` into `width x height` linear HDR RGBA, row 0 at the top.
/// Covered pixels have alpha 1, the background is (0, 0, 0, 0). Both faces of every triangle
/// are drawn, so open meshes and inconsistent winding still show.
pub fn render(
    ctx: &GpuContext,
    scene: &Scene,
    radiance: &[[f32; 3]],
    camera: &Camera,
    width: u32,
    height: u32,
) -> Result<Vec<[f32; 4]>> {
    let target = Target::new(width, height, ColorFormat::for_adapter(ctx)?, &ctx.limits)?;
    check_render_inputs(scene, radiance, &ctx.limits)?;
    camera.validate()?;
    let (near, far) = depth_range(camera, &scene.positions);
    let params = RenderParams {
        clip_from_world: camera
            .clip_from_world(width as f32 / height as f32, near, far)
            .to_cols_array_2d(),
    };
    let readback = ctx.checked("render", || draw(ctx, scene, radiance, &params, &target))?;
    let padded: Vec<u8> = ctx.read_back(&readback, target.readback_bytes())?;
    Ok(unpad_rows(&padded, &target))
}

/// Image size and the row pitch the texture-to-buffer copy needs.
struct Target {
    width: u32,
    height: u32,
    format: ColorFormat,
    /// Row pitch in bytes: copies require multiples of COPY_BYTES_PER_ROW_ALIGNMENT.
    padded_row_bytes: u32,
}

impl Target {
    fn new(width: u32, height: u32, format: ColorFormat, limits: &wgpu::Limits) -> Result<Target> {
        let max = limits.max_texture_dimension_2d;
        if width == 0 || height == 0 || width > max || height > max {
            return Err(Error::Options(format!(
                "image size {width}x{height} must lie within 1x1 to {max}x{max}"
            )));
        }
        let align = wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
        let padded_row_bytes = (width * format.bytes_per_pixel()).div_ceil(align) * align;
        let target = Target {
            width,
            height,
            format,
            padded_row_bytes,
        };
        if target.readback_bytes() > limits.max_buffer_size {
            return Err(Error::Options(format!(
                "image size {width}x{height} needs {} bytes of read-back buffer; the adapter allows {}",
                target.readback_bytes(),
                limits.max_buffer_size
            )));
        }
        Ok(target)
    }

    fn readback_bytes(&self) -> u64 {
        self.padded_row_bytes as u64 * self.height as u64
    }

    fn extent(&self) -> wgpu::Extent3d {
        wgpu::Extent3d {
            width: self.width,
            height: self.height,
            depth_or_array_layers: 1,
        }
    }
}

/// What `render` needs of the mesh: triangles with valid indices, finite positions, one
/// radiance per vertex, vertex data within the adapter's buffer size.
fn check_render_inputs(scene: &Scene, radiance: &[[f32; 3]], limits: &wgpu::Limits) -> Result<()> {
    let vertices = scene.vertex_count();
    if radiance.len() != vertices {
        return Err(Error::Options(format!(
            "render: {} radiance values for {vertices} vertices",
            radiance.len()
        )));
    }
    if scene.triangles.is_empty() {
        return Err(Error::Geometry("render: the mesh has no triangles".into()));
    }
    if let Some(t) = scene
        .triangles
        .iter()
        .position(|t| t.iter().any(|&i| i as usize >= vertices))
    {
        return Err(Error::Geometry(format!(
            "render: triangle {t} indexes past the {vertices} vertices"
        )));
    }
    if let Some(v) = scene.positions.iter().position(|p| !p.is_finite()) {
        return Err(Error::Geometry(format!(
            "render: vertex {v} has a non-finite position"
        )));
    }
    let largest = (vertices * 12).max(scene.triangles.len() * 12) as u64;
    if largest > limits.max_buffer_size {
        return Err(Error::Options(format!(
            "render: {largest} bytes of vertex data exceed the adapter's {} byte buffers",
            limits.max_buffer_size
        )));
    }
    Ok(())
}

/// Near and far planes hugging the mesh's bounding sphere, so depth precision is spent on it.
/// A camera inside the sphere gets a near plane at a fixed fraction of the far one.
fn depth_range(camera: &Camera, positions: &[Vec3]) -> (f32, f32) {
    let (min, max) = bounds(positions);
    let center = (min + max) * 0.5;
    let radius = usable_radius((max - min).length() * 0.5, center);
    let distance = (center - camera.eye).length();
    let far = (distance + radius) * 1.01;
    let near = ((distance - radius) * 0.99).max(far * 1e-4);
    (near, far)
}

/// Records and submits the draw and the copy of the colour target into a buffer, which is
/// returned for reading back.
fn draw(
    ctx: &GpuContext,
    scene: &Scene,
    radiance: &[[f32; 3]],
    params: &RenderParams,
    target: &Target,
) -> wgpu::Buffer {
    let device = &ctx.device;
    let pipeline = pipeline(device, target.format.texture());
    let uniform = ctx.uniform("render params", params);
    let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("render"),
        layout: &pipeline.get_bind_group_layout(0),
        entries: &[wgpu::BindGroupEntry {
            binding: 0,
            resource: uniform.as_entire_binding(),
        }],
    });
    let positions = vertex_buffer(device, "positions", bytemuck::cast_slice(&scene.positions));
    let colours = vertex_buffer(device, "radiance", bytemuck::cast_slice(radiance));
    let indices = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("indices"),
        contents: bytemuck::cast_slice(&scene.triangles),
        usage: wgpu::BufferUsages::INDEX,
    });
    let color = attachment(
        device,
        target,
        target.format.texture(),
        wgpu::TextureUsages::COPY_SRC,
    );
    let depth = attachment(device, target, DEPTH_FORMAT, wgpu::TextureUsages::empty());
    let readback = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("render read-back"),
        size: target.readback_bytes(),
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });

    let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
        label: Some("render"),
    });
    {
        let color_view = color.create_view(&Default::default());
        let depth_view = depth.create_view(&Default::default());
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("render"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &color_view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &depth_view,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(1.0),
                    store: wgpu::StoreOp::Discard,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &bind_group, &[]);
        pass.set_vertex_buffer(0, positions.slice(..));
        pass.set_vertex_buffer(1, colours.slice(..));
        pass.set_index_buffer(indices.slice(..), wgpu::IndexFormat::Uint32);
        pass.draw_indexed(0..scene.triangles.len() as u32 * 3, 0, 0..1);
    }
    encoder.copy_texture_to_buffer(
        wgpu::TexelCopyTextureInfo {
            texture: &color,
            mip_level: 0,
            origin: wgpu::Origin3d::ZERO,
            aspect: wgpu::TextureAspect::All,
        },
        wgpu::TexelCopyBufferInfo {
            buffer: &readback,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(target.padded_row_bytes),
                rows_per_image: Some(target.height),
            },
        },
        target.extent(),
    );
    ctx.queue.submit([encoder.finish()]);
    readback
}

fn vertex_buffer(device: &wgpu::Device, label: &str, contents: &[u8]) -> wgpu::Buffer {
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents,
        usage: wgpu::BufferUsages::VERTEX,
    })
}

fn attachment(
    device: &wgpu::Device,
    target: &Target,
    format: wgpu::TextureFormat,
    extra_usage: wgpu::TextureUsages,
) -> wgpu::Texture {
    device.create_texture(&wgpu::TextureDescriptor {
        label: Some("render target"),
        size: target.extent(),
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT | extra_usage,
        view_formats: &[],
    })
}

fn pipeline(device: &wgpu::Device, color_format: wgpu::TextureFormat) -> wgpu::RenderPipeline {
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("render"),
        source: wgpu::ShaderSource::Wgsl(shaders::render_shader().into()),
    });
    let bind_group_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("render"),
        entries: &[wgpu::BindGroupLayoutEntry {
            binding: 0,
            visibility: wgpu::ShaderStages::VERTEX,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Uniform,
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        }],
    });
    let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("render"),
        bind_group_layouts: &[Some(&bind_group_layout)],
        immediate_size: 0,
    });
    let vec3_at = |location| {
        [wgpu::VertexAttribute {
            format: wgpu::VertexFormat::Float32x3,
            offset: 0,
            shader_location: location,
        }]
    };
    let (position_attribute, radiance_attribute) = (vec3_at(0), vec3_at(1));
    let vec3_buffer = |attributes| wgpu::VertexBufferLayout {
        array_stride: 12,
        step_mode: wgpu::VertexStepMode::Vertex,
        attributes,
    };
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("render"),
        layout: Some(&layout),
        vertex: wgpu::VertexState {
            module: &module,
            entry_point: Some("vs_main"),
            compilation_options: Default::default(),
            buffers: &[
                Some(vec3_buffer(&position_attribute)),
                Some(vec3_buffer(&radiance_attribute)),
            ],
        },
        primitive: wgpu::PrimitiveState {
            topology: wgpu::PrimitiveTopology::TriangleList,
            cull_mode: None,
            ..Default::default()
        },
        depth_stencil: Some(wgpu::DepthStencilState {
            format: DEPTH_FORMAT,
            depth_write_enabled: Some(true),
            depth_compare: Some(wgpu::CompareFunction::Less),
            stencil: Default::default(),
            bias: Default::default(),
        }),
        multisample: Default::default(),
        fragment: Some(wgpu::FragmentState {
            module: &module,
            entry_point: Some("fs_main"),
            compilation_options: Default::default(),
            targets: &[Some(wgpu::ColorTargetState {
                format: color_format,
                blend: None,
                write_mask: wgpu::ColorWrites::ALL,
            })],
        }),
        multiview_mask: None,
        cache: None,
    })
}

/// Drops the row padding the copy alignment added.
fn unpad_rows(padded: &[u8], target: &Target) -> Vec<[f32; 4]> {
    let row_bytes = (target.width * target.format.bytes_per_pixel()) as usize;
    padded
        .chunks_exact(target.padded_row_bytes as usize)
        .take(target.height as usize)
        .flat_map(|row| target.format.decode(&row[..row_bytes]))
        .collect()
}

/// Panels placed left to right (e.g. unshadowed | shadowed | interreflected), each
/// `width x height`; the result is `images.len() * width` wide.
///
/// Returns a `Result` rather than panicking on a panel of the wrong size.
pub fn side_by_side(images: &[Vec<[f32; 4]>], width: u32, height: u32) -> Result<Vec<[f32; 4]>> {
    let panel = width as usize * height as usize;
    if images.is_empty() || panel == 0 {
        return Err(Error::Options(
            "side by side: no panels, or panels of zero size".into(),
        ));
    }
    if let Some(i) = images.iter().position(|image| image.len() != panel) {
        return Err(Error::Options(format!(
            "side by side: panel {i} has {} pixels, not {width}x{height}",
            images[i].len()
        )));
    }
    let w = width as usize;
    Ok((0..height as usize)
        .flat_map(|y| images.iter().flat_map(move |image| &image[y * w..][..w]))
        .copied()
        .collect())
}

/// How linear radiance becomes display values before sRGB encoding (PNG only).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum ToneMap {
    /// Clamp to [0, 1]: radiance 1 is white, brighter is clipped.
    None,
    /// `x / (1 + x)` per channel: nothing clips, highlights compress.
    #[default]
    Reinhard,
    /// Narkowicz's fit of the ACES filmic curve per channel: more contrast than Reinhard.
    Aces,
}

/// Linear radiance → display-linear value in [0, 1], after scaling by `2^exposure_stops`.
pub fn tone_map(value: f32, tone: ToneMap, exposure_stops: f32) -> f32 {
    let x = (value * exposure_stops.exp2()).max(0.0);
    let mapped = match tone {
        ToneMap::None => x,
        ToneMap::Reinhard => x / (1.0 + x),
        ToneMap::Aces => (x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14),
    };
    mapped.clamp(0.0, 1.0)
}

fn to_byte(unit: f32) -> u8 {
    // NaN clamps to NaN, which `as` turns into 0: a black pixel, not a panic.
    (unit.clamp(0.0, 1.0) * 255.0 + 0.5) as u8
}

/// 8-bit sRGB RGBA: colour tone-mapped and encoded, alpha (coverage) kept linear.
pub fn to_rgba8(pixels: &[[f32; 4]], tone: ToneMap, exposure_stops: f32) -> Vec<u8> {
    pixels
        .iter()
        .flat_map(|p| {
            let [r, g, b] =
                [p[0], p[1], p[2]].map(|c| to_byte(srgb_encode(tone_map(c, tone, exposure_stops))));
            [r, g, b, to_byte(p[3])]
        })
        .collect()
}

/// Writes `pixels` (`width x height` linear RGBA, row 0 at the top) atomically, in the format
/// the extension names: `.png` tone-mapped 8-bit sRGB with alpha, `.exr` linear 32-bit float
/// RGBA (tone map and exposure do not apply: an HDR file keeps the radiance).
pub fn write_image(
    path: &Path,
    pixels: &[[f32; 4]],
    width: u32,
    height: u32,
    tone: ToneMap,
    exposure_stops: f32,
) -> Result<()> {
    if width == 0 || height == 0 || pixels.len() != width as usize * height as usize {
        return Err(Error::Options(format!(
            "{}: {} pixels do not make a {width}x{height} image",
            path.display(),
            pixels.len()
        )));
    }
    if !exposure_stops.is_finite() {
        return Err(Error::Options(format!(
            "exposure {exposure_stops} is not finite"
        )));
    }
    let bytes = match ImageFormat::of(path)? {
        ImageFormat::Png => encode_png(pixels, width, height, tone, exposure_stops),
        ImageFormat::Exr => encode_exr(pixels, width, height),
    }
    .map_err(|message| Error::io(path, std::io::Error::other(message)))?;
    write_atomically(path, &bytes)
}

#[derive(Clone, Copy)]
enum ImageFormat {
    Png,
    Exr,
}

impl ImageFormat {
    fn of(path: &Path) -> Result<ImageFormat> {
        format_by_extension(
            path,
            &[("png", ImageFormat::Png), ("exr", ImageFormat::Exr)],
            "image files",
        )
    }
}

fn encode_png(
    pixels: &[[f32; 4]],
    width: u32,
    height: u32,
    tone: ToneMap,
    exposure_stops: f32,
) -> std::result::Result<Vec<u8>, String> {
    use image::ImageEncoder;
    let mut bytes = Vec::new();
    image::codecs::png::PngEncoder::new(&mut bytes)
        .write_image(
            &to_rgba8(pixels, tone, exposure_stops),
            width,
            height,
            image::ExtendedColorType::Rgba8,
        )
        .map_err(|e| e.to_string())?;
    Ok(bytes)
}

fn encode_exr(
    pixels: &[[f32; 4]],
    width: u32,
    height: u32,
) -> std::result::Result<Vec<u8>, String> {
    use exr::prelude::{Image, SpecificChannels, Vec2, WritableImage};
    let w = width as usize;
    let channels = SpecificChannels::rgba(|Vec2(x, y): Vec2<usize>| {
        let [r, g, b, a] = pixels[y * w + x];
        (r, g, b, a)
    });
    let mut bytes = Cursor::new(Vec::new());
    Image::from_channels((w, height as usize), channels)
        .write()
        .to_buffered(&mut bytes)
        .map_err(|e| e.to_string())?;
    Ok(bytes.into_inner())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bake::{bake, Backend, BakeOptions, Mode, NoProgress};
    use crate::device;
    use crate::scene::builtin::icosphere;
    use crate::scene::prepare::prepare;
    use std::path::PathBuf;
    use std::sync::OnceLock;
    use std::time::Instant;

    /// The device for GPU tests, or `None` (reason printed) where there is no adapter outside
    /// CI; under CI a missing adapter fails, as in tests/common.
    fn gpu_context() -> Option<&'static GpuContext> {
        static GPU: OnceLock<Option<GpuContext>> = OnceLock::new();
        GPU.get_or_init(device::any_adapter_or_skip).as_ref()
    }

    /// A scratch directory removed on drop.
    struct Scratch(PathBuf);

    impl Scratch {
        fn new(name: &str) -> Self {
            let dir =
                std::env::temp_dir().join(format!("prt-gpu-render-{name}-{}", std::process::id()));
            let _ = std::fs::remove_dir_all(&dir);
            std::fs::create_dir_all(&dir).unwrap();
            Scratch(dir)
        }

        fn entries(&self) -> Vec<String> {
            let mut names: Vec<String> = std::fs::read_dir(&self.0)
                .unwrap()
                .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
                .collect();
            names.sort();
            names
        }
    }

    impl Drop for Scratch {
        fn drop(&mut self) {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }

    fn unit_sphere(center: Vec3) -> Scene {
        prepare(icosphere(center, 1.0, 4)).unwrap().0
    }

    fn transfer(bands: u32, channels: u32, coeffs: Vec<f32>) -> Transfer {
        let per_vertex = (channels * bands * bands) as usize;
        Transfer {
            bands,
            channels,
            vertex_count: coeffs.len() / per_vertex,
            coeffs,
        }
    }

    #[test]
    fn relight_is_the_dot_product_per_channel() {
        // Two vertices, 2 bands (4 coefficients), RGB.
        let coeffs: Vec<f32> = (0..2 * 3 * 4).map(|i| i as f32 * 0.5 - 3.0).collect();
        let light = ShLight {
            bands: 2,
            coeffs: vec![
                [1.0, 2.0, -1.0],
                [0.5, 0.0, 3.0],
                [-2.0, 1.0, 0.25],
                [4.0, -0.5, 1.5],
            ],
        };
        let got = relight(&transfer(2, 3, coeffs.clone()), &light).unwrap();
        for (v, rgb) in got.iter().enumerate() {
            for (c, value) in rgb.iter().enumerate() {
                let t = &coeffs[(v * 3 + c) * 4..][..4];
                let expected = t[0] * light.coeffs[0][c]
                    + t[1] * light.coeffs[1][c]
                    + t[2] * light.coeffs[2][c]
                    + t[3] * light.coeffs[3][c];
                assert!(
                    (value - expected).abs() < 1e-5,
                    "v{v} c{c}: {value} vs {expected}"
                );
            }
        }
        // Vertex 0, red: t = [-3, -2.5, -2, -1.5], l = [1, 0.5, -2, 4] by hand.
        assert!((got[0][0] - (-3.0 - 1.25 + 4.0 - 6.0)).abs() < 1e-6);
    }

    #[test]
    fn relight_one_channel_transfer_lights_all_channels() {
        let light = ShLight {
            bands: 1,
            coeffs: vec![[1.0, 2.0, 3.0]],
        };
        let got = relight(&transfer(1, 1, vec![0.5, 2.0]), &light).unwrap();
        assert_eq!(got, vec![[0.5, 1.0, 1.5], [2.0, 4.0, 6.0]]);
    }

    #[test]
    fn relight_sums_over_the_bands_both_sides_have() {
        let t = transfer(2, 1, vec![1.0, 10.0, 100.0, 1000.0]);
        // A 1-band light: the missing bands count as zero.
        let dc_only = ShLight {
            bands: 1,
            coeffs: vec![[2.0; 3]],
        };
        assert_eq!(relight(&t, &dc_only).unwrap(), vec![[2.0; 3]]);
        // A 3-band light: band 2 meets no transfer and is ignored.
        let mut wide = ShLight {
            bands: 3,
            coeffs: vec![[1.0; 3]; 9],
        };
        wide.coeffs[4..].iter_mut().for_each(|l| *l = [1e6; 3]);
        assert_eq!(relight(&t, &wide).unwrap(), vec![[1111.0; 3]]);
    }

    #[test]
    fn relight_rejects_inconsistent_inputs() {
        let light = ShLight::constant(2, [1.0; 3]);
        let mut short = transfer(2, 3, vec![0.0; 24]);
        short.coeffs.pop();
        assert!(relight(&short, &light).is_err());
        assert!(relight(&transfer(2, 2, vec![0.0; 16]), &light).is_err());
        let mut no_bands = transfer(2, 3, vec![0.0; 24]);
        no_bands.bands = 0;
        assert!(relight(&no_bands, &light).is_err());
        let bad_light = ShLight {
            bands: 2,
            coeffs: vec![[1.0; 3]; 3],
        };
        assert!(relight(&transfer(2, 3, vec![0.0; 24]), &bad_light).is_err());
        let empty = transfer(2, 3, Vec::new());
        assert_eq!(relight(&empty, &light).unwrap(), Vec::<[f32; 3]>::new());
    }

    #[test]
    fn white_unshadowed_sphere_under_unit_light_relights_to_one() {
        let options = BakeOptions {
            bands: 4,
            samples: 1024,
            mode: Mode::Unshadowed,
            albedo: Some(Vec3::ONE),
            ..BakeOptions::default()
        };
        let (baked, _) = bake(
            icosphere(Vec3::ZERO, 1.0, 2),
            &options,
            &Backend::Cpu,
            &NoProgress,
        )
        .unwrap();
        let radiance = relight(&baked.transfer, &ShLight::constant(4, [1.0; 3])).unwrap();
        assert_eq!(radiance.len(), baked.scene.vertex_count());
        let worst = radiance
            .iter()
            .flatten()
            .map(|v| (v - 1.0).abs())
            .fold(0.0f32, f32::max);
        // 1024 stratified samples integrate the clamped cosine to well under 1%.
        assert!(worst < 1e-2, "furthest from the white furnace: {worst}");
    }

    #[test]
    fn framing_centres_the_mesh_and_keeps_it_in_view() {
        let (min, max) = (Vec3::new(3.0, -1.0, 10.0), Vec3::new(5.0, 4.0, 11.0));
        let camera = Camera::framing(min, max);
        camera.validate().unwrap();
        let center = (min + max) * 0.5;
        assert_eq!(camera.target, center);
        // A three-quarter view: in front (+Z), to the right (+X) and above.
        let offset = camera.eye - center;
        assert!(offset.x > 0.0 && offset.y > 0.0 && offset.z > offset.x);
        let clip = camera.clip_from_world(1.0, 0.1, 100.0);
        let ndc = clip.project_point3(center);
        assert!(ndc.x.abs() < 1e-5 && ndc.y.abs() < 1e-5, "{ndc}");
        for i in 0..8 {
            let corner = Vec3::select(
                glam::BVec3::new(i & 1 != 0, i & 2 != 0, i & 4 != 0),
                max,
                min,
            );
            let p = clip.project_point3(corner);
            assert!(p.x.abs() < 1.0 && p.y.abs() < 1.0, "corner {corner} at {p}");
        }
    }

    #[test]
    fn framing_a_point_still_gives_a_valid_camera() {
        Camera::framing(Vec3::ONE, Vec3::ONE).validate().unwrap();
        Camera::framing(Vec3::ZERO, Vec3::splat(f32::INFINITY))
            .validate()
            .unwrap_err();
    }

    #[test]
    fn camera_parses_from_the_command_line_form() {
        let camera: Camera = "0,1,5, 0,0,0".parse().unwrap();
        assert_eq!(camera.eye, Vec3::new(0.0, 1.0, 5.0));
        assert_eq!(camera.target, Vec3::ZERO);
        assert_eq!(camera.up, Vec3::Y);
        assert_eq!(camera.vertical_fov_deg, DEFAULT_FOV_DEG);
        let wide: Camera = "1,2,3,4,5,6,75".parse().unwrap();
        assert_eq!(wide.vertical_fov_deg, 75.0);
        for bad in [
            "",
            "1,2,3",
            "1,2,3,4,5,6,7,8",
            "a,0,0,0,0,0",
            "0,0,0,0,0,0",
            "0,0,1,0,0,0,180",
            "0,0,1,0,0,0,NaN",
        ] {
            assert!(bad.parse::<Camera>().is_err(), "{bad:?} was accepted");
        }
    }

    #[test]
    fn looking_straight_down_still_has_a_view() {
        let camera: Camera = "0,5,0,0,0,0".parse().unwrap();
        let m = camera.clip_from_world(1.0, 0.1, 10.0);
        assert!(m.is_finite());
        assert!(m.project_point3(Vec3::ZERO).truncate().length() < 1e-5);
    }

    #[test]
    fn tone_maps_behave_at_their_landmarks() {
        assert_eq!(tone_map(0.25, ToneMap::None, 0.0), 0.25);
        assert_eq!(tone_map(0.25, ToneMap::None, 1.0), 0.5);
        assert_eq!(tone_map(3.0, ToneMap::None, 0.0), 1.0);
        assert_eq!(tone_map(-1.0, ToneMap::None, 0.0), 0.0);
        assert_eq!(tone_map(1.0, ToneMap::Reinhard, 0.0), 0.5);
        assert!(tone_map(1e6, ToneMap::Reinhard, 0.0) > 0.999);
        assert_eq!(tone_map(0.0, ToneMap::Aces, 0.0), 0.0);
        assert!((tone_map(0.18, ToneMap::Aces, 0.0) - 0.2670).abs() < 1e-3);
        assert_eq!(tone_map(100.0, ToneMap::Aces, 0.0), 1.0);
        for tone in [ToneMap::None, ToneMap::Reinhard, ToneMap::Aces] {
            let values: Vec<f32> = (0..200)
                .map(|i| tone_map(i as f32 * 0.05, tone, 0.0))
                .collect();
            assert!(
                values.windows(2).all(|w| w[0] <= w[1]),
                "{tone:?} is not monotonic"
            );
        }
    }

    #[test]
    fn rgba8_pixels_are_srgb_encoded_with_linear_alpha() {
        assert_eq!(
            to_rgba8(&[[0.5, 1.0, 0.0, 1.0]], ToneMap::None, 0.0),
            [188, 255, 0, 255]
        );
        assert_eq!(
            to_rgba8(&[[f32::NAN, 0.0, 0.0, 0.0]], ToneMap::None, 0.0),
            [0, 0, 0, 0]
        );
    }

    #[test]
    fn side_by_side_places_panels_left_to_right() {
        let panel = |v: f32| vec![[v, v, v, 1.0]; 6];
        let mut first = panel(1.0);
        first[3] = [9.0; 4]; // (x 0, y 1) of a 3x2 panel
        let joined = side_by_side(&[first, panel(2.0), panel(3.0)], 3, 2).unwrap();
        assert_eq!(joined.len(), 18);
        let row0: Vec<f32> = joined[..9].iter().map(|p| p[0]).collect();
        assert_eq!(row0, [1.0, 1.0, 1.0, 2.0, 2.0, 2.0, 3.0, 3.0, 3.0]);
        assert_eq!(joined[9], [9.0; 4]);
        assert!(side_by_side(&[], 3, 2).is_err());
        assert!(side_by_side(&[panel(1.0), vec![[0.0; 4]; 5]], 3, 2).is_err());
        assert!(side_by_side(&[Vec::new()], 0, 2).is_err());
    }

    #[test]
    fn png_has_the_size_mean_and_centre_asked_for() {
        let scratch = Scratch::new("png");
        let (w, h) = (5u32, 3u32);
        // Left columns linear 0.5 (sRGB byte 188), the rest black and transparent.
        let pixels: Vec<[f32; 4]> = (0..w * h)
            .map(|i| {
                if i % w < 3 {
                    [0.5, 0.5, 0.5, 1.0]
                } else {
                    [0.0; 4]
                }
            })
            .collect();
        let path = scratch.0.join("preview.png");
        write_image(&path, &pixels, w, h, ToneMap::None, 0.0).unwrap();
        let png = image::open(&path).unwrap().into_rgba8();
        assert_eq!(png.dimensions(), (w, h));
        assert_eq!(png.get_pixel(2, 1).0, [188, 188, 188, 255]);
        let mean_red = png.pixels().map(|p| p.0[0] as f64).sum::<f64>() / (w * h) as f64;
        assert!((mean_red - 188.0 * 3.0 / 5.0).abs() < 1e-9, "{mean_red}");
        assert_eq!(scratch.entries(), ["preview.png"]);
    }

    #[test]
    fn exr_keeps_linear_hdr_values() {
        let scratch = Scratch::new("exr");
        let pixels = vec![
            [0.25, 7.5, 1000.0, 1.0],
            [0.0; 4],
            [1.0, 2.0, 3.0, 0.5],
            [-1.0, 0.0, 0.0, 1.0],
        ];
        let path = scratch.0.join("preview.exr");
        write_image(&path, &pixels, 2, 2, ToneMap::Aces, 3.0).unwrap();
        let image = exr::prelude::read_first_rgba_layer_from_file(
            &path,
            |size, _| vec![[0.0f32; 4]; size.0 * size.1],
            |out: &mut Vec<[f32; 4]>, pos, (r, g, b, a): (f32, f32, f32, f32)| {
                out[pos.1 * 2 + pos.0] = [r, g, b, a];
            },
        )
        .unwrap();
        assert_eq!(image.layer_data.channel_data.pixels, pixels);
    }

    #[test]
    fn bad_image_writes_fail_without_leaving_files() {
        let scratch = Scratch::new("bad");
        let pixels = vec![[1.0; 4]; 4];
        let png = scratch.0.join("a.png");
        assert!(write_image(&png, &pixels, 3, 2, ToneMap::None, 0.0).is_err());
        assert!(write_image(&png, &pixels, 0, 0, ToneMap::None, 0.0).is_err());
        assert!(write_image(&png, &pixels, 2, 2, ToneMap::None, f32::NAN).is_err());
        assert!(write_image(&scratch.0.join("a.jpg"), &pixels, 2, 2, ToneMap::None, 0.0).is_err());
        assert!(write_image(&scratch.0.join("a"), &pixels, 2, 2, ToneMap::None, 0.0).is_err());
        let missing = scratch.0.join("missing").join("a.png");
        assert!(write_image(&missing, &pixels, 2, 2, ToneMap::None, 0.0).is_err());
        assert!(scratch.entries().is_empty(), "{:?}", scratch.entries());
    }

    #[test]
    fn render_inputs_are_checked_before_any_gpu_work() {
        let limits = wgpu::Limits::default();
        let scene = unit_sphere(Vec3::ZERO);
        let ones = vec![[1.0; 3]; scene.vertex_count()];
        check_render_inputs(&scene, &ones, &limits).unwrap();
        assert!(check_render_inputs(&scene, &ones[1..], &limits).is_err());
        let mut bad_index = scene.clone();
        bad_index.triangles[7][1] = scene.vertex_count() as u32;
        assert!(check_render_inputs(&bad_index, &ones, &limits).is_err());
        let mut no_triangles = scene.clone();
        no_triangles.triangles.clear();
        assert!(check_render_inputs(&no_triangles, &ones, &limits).is_err());
        let mut nan = scene.clone();
        nan.positions[3].y = f32::NAN;
        assert!(check_render_inputs(&nan, &ones, &limits).is_err());
        let f32x4 = ColorFormat::Rgba32Float;
        for (w, h) in [(0, 10), (10, 0), (limits.max_texture_dimension_2d + 1, 1)] {
            assert!(Target::new(w, h, f32x4, &limits).is_err(), "{w}x{h}");
        }
    }

    #[test]
    fn read_back_rows_lose_their_padding() {
        let limits = wgpu::Limits::default();
        // 3 pixels of 16 bytes pad to one 256-byte row, 16 pixels.
        let target = Target::new(3, 2, ColorFormat::Rgba32Float, &limits).unwrap();
        assert_eq!(target.padded_row_bytes, 256);
        let padded: Vec<f32> = (0..32).flat_map(|i| [i as f32; 4]).collect();
        let rows = unpad_rows(bytemuck::cast_slice(&padded), &target);
        let reds: Vec<f32> = rows.iter().map(|p| p[0]).collect();
        assert_eq!(reds, [0.0, 1.0, 2.0, 16.0, 17.0, 18.0]);
        // Half floats: 8 bytes a pixel, 32 pixels a padded row.
        let target = Target::new(2, 2, ColorFormat::Rgba16Float, &limits).unwrap();
        let one_two: [u16; 4] = [0x3c00, 0x4000, 0x3800, 0xc000]; // 1, 2, 0.5, -2
        let mut padded = vec![0u16; 2 * 32 * 4];
        padded[..4].copy_from_slice(&one_two);
        padded[32 * 4 + 4..32 * 4 + 8].copy_from_slice(&one_two);
        let rows = unpad_rows(bytemuck::cast_slice(&padded), &target);
        assert_eq!(
            rows,
            [
                [1.0, 2.0, 0.5, -2.0],
                [0.0; 4],
                [0.0; 4],
                [1.0, 2.0, 0.5, -2.0]
            ]
        );
    }

    #[test]
    fn half_floats_decode_exactly() {
        assert_eq!(f16_to_f32(0x0000), 0.0);
        assert_eq!(f16_to_f32(0x3c00), 1.0);
        assert_eq!(f16_to_f32(0x3555), 0.333_251_95);
        assert_eq!(f16_to_f32(0x7bff), 65504.0);
        assert_eq!(f16_to_f32(0x0001), 2f32.powi(-24));
        assert_eq!(f16_to_f32(0x03ff), 1023.0 * 2f32.powi(-24));
        assert_eq!(f16_to_f32(0xfc00), f32::NEG_INFINITY);
        assert!(f16_to_f32(0x7e00).is_nan());
        assert!(f16_to_f32(0x8000).is_sign_negative());
    }

    /// Where the centre of pixel (x, y) lies in normalised device coordinates.
    fn pixel_ndc(x: u32, y: u32, size: u32) -> (f32, f32) {
        let to_ndc = |i: u32| (i as f32 + 0.5) / size as f32 * 2.0 - 1.0;
        (to_ndc(x), -to_ndc(y))
    }

    #[test]
    fn white_sphere_renders_one_inside_its_projected_disc() {
        let Some(ctx) = gpu_context() else { return };
        let scene = unit_sphere(Vec3::ZERO);
        let ones = vec![[1.0; 3]; scene.vertex_count()];
        let camera: Camera = "0,0,4,0,0,0,40".parse().unwrap();
        let size = 256;
        let image = render(ctx, &scene, &ones, &camera, size, size).unwrap();
        assert_eq!(image.len(), (size * size) as usize);

        let mut covered = 0;
        for p in &image {
            if p[3] == 0.0 {
                assert_eq!(*p, [0.0; 4], "background must be transparent black");
            } else {
                covered += 1;
                assert!(
                    p.iter().all(|v| (v - 1.0).abs() < 1e-3),
                    "covered pixel {p:?}"
                );
            }
        }
        // The silhouette of a sphere of radius r seen from distance d is a disc of NDC radius
        // f r / sqrt(d^2 - r^2), f = 1 / tan(fov / 2); the NDC square has area 4.
        let f = 1.0 / 20f32.to_radians().tan();
        let disc = f / 15f32.sqrt();
        let expected = std::f32::consts::PI * disc * disc / 4.0;
        let fraction = covered as f32 / image.len() as f32;
        assert!(
            (fraction / expected - 1.0).abs() < 0.015,
            "covered {fraction}, disc {expected}"
        );
        let at = |x: u32, y: u32| image[(y * size + x) as usize];
        assert_eq!(at(size / 2, size / 2)[3], 1.0, "centre");
        for (x, y) in [(0, 0), (size - 1, 0), (0, size - 1), (size - 1, size - 1)] {
            assert_eq!(at(x, y), [0.0; 4], "corner {x},{y}");
        }
        // Along both axes: inside at 80% of the disc radius, outside at 110%.
        for (x, y) in [
            (size / 2, 0),
            (0, size / 2),
            (size / 2, size - 1),
            (size - 1, size / 2),
        ] {
            let (nx, ny) = pixel_ndc(x, y, size);
            let towards = |k: f32| {
                let t = k * disc / nx.abs().max(ny.abs());
                let px = ((nx * t + 1.0) / 2.0 * size as f32) as u32;
                let py = ((1.0 - ny * t) / 2.0 * size as f32) as u32;
                at(px, py)[3]
            };
            assert_eq!(towards(0.8), 1.0);
            assert_eq!(towards(1.1), 0.0);
        }
    }

    #[test]
    fn framed_off_centre_mesh_lands_in_the_image_centre() {
        let Some(ctx) = gpu_context() else { return };
        let scene = unit_sphere(Vec3::new(10.0, -3.0, 4.0));
        let ones = vec![[1.0; 3]; scene.vertex_count()];
        let camera = Camera::framing_scene(&scene);
        let (w, h) = (200, 120);
        let image = render(ctx, &scene, &ones, &camera, w, h).unwrap();
        let (mut sum_x, mut sum_y, mut n) = (0.0, 0.0, 0.0);
        for (i, p) in image.iter().enumerate() {
            if p[3] > 0.0 {
                sum_x += (i as u32 % w) as f64 + 0.5;
                sum_y += (i as u32 / w) as f64 + 0.5;
                n += 1.0;
            }
        }
        assert!(n > 0.0);
        let (cx, cy) = (sum_x / n, sum_y / n);
        assert!(
            (cx - w as f64 / 2.0).abs() < 1.0 && (cy - h as f64 / 2.0).abs() < 1.0,
            "{cx},{cy}"
        );
        // The whole sphere is in view: no covered pixel on the border.
        let border = image.iter().enumerate().filter(|(i, p)| {
            let (x, y) = (*i as u32 % w, *i as u32 / w);
            p[3] > 0.0 && (x == 0 || y == 0 || x == w - 1 || y == h - 1)
        });
        assert_eq!(border.count(), 0);
    }

    #[test]
    fn rendered_png_of_a_white_sphere() {
        let Some(ctx) = gpu_context() else { return };
        let scratch = Scratch::new("sphere");
        let scene = unit_sphere(Vec3::ZERO);
        let ones = vec![[1.0; 3]; scene.vertex_count()];
        let camera = Camera::framing_scene(&scene);
        let size = 128;
        let image = render(ctx, &scene, &ones, &camera, size, size).unwrap();
        let coverage = image.iter().filter(|p| p[3] > 0.0).count() as f64 / image.len() as f64;
        let path = scratch.0.join("sphere.png");
        write_image(&path, &image, size, size, ToneMap::None, 0.0).unwrap();
        let png = image::open(&path).unwrap().into_rgba8();
        assert_eq!(png.dimensions(), (size, size));
        assert_eq!(png.get_pixel(size / 2, size / 2).0, [255; 4]);
        assert_eq!(png.get_pixel(0, 0).0, [0; 4]);
        let mean =
            |c: usize| png.pixels().map(|p| p.0[c] as f64).sum::<f64>() / png.len() as f64 * 4.0;
        for c in 0..4 {
            assert!((mean(c) / 255.0 - coverage).abs() < 1e-9, "channel {c}");
        }
        // Reinhard maps radiance 1 to 0.5, sRGB byte 188.
        write_image(&path, &image, size, size, ToneMap::Reinhard, 0.0).unwrap();
        let png = image::open(&path).unwrap().into_rgba8();
        assert_eq!(png.get_pixel(size / 2, size / 2).0, [188, 188, 188, 255]);
        assert_eq!(scratch.entries(), ["sphere.png"]);
    }

    #[test]
    fn render_refuses_bad_inputs_without_panicking() {
        let Some(ctx) = gpu_context() else { return };
        let scene = unit_sphere(Vec3::ZERO);
        let ones = vec![[1.0; 3]; scene.vertex_count()];
        let camera = Camera::framing_scene(&scene);
        assert!(render(ctx, &scene, &ones, &camera, 0, 64).is_err());
        assert!(render(ctx, &scene, &ones, &camera, 64, 0).is_err());
        assert!(render(ctx, &scene, &ones[..10], &camera, 64, 64).is_err());
        let mut blind = camera;
        blind.eye = blind.target;
        assert!(render(ctx, &scene, &ones, &blind, 64, 64).is_err());
        // The device is still usable afterwards.
        assert_eq!(render(ctx, &scene, &ones, &camera, 8, 8).unwrap().len(), 64);
    }

    #[test]
    #[ignore = "timing: cargo test --release --lib render::tests::timing -- --ignored --nocapture"]
    fn timing_relight_and_render() {
        let vertices = 100_000;
        let bands = 4;
        let coeffs: Vec<f32> = (0..vertices * 3 * 16)
            .map(|i| (i % 97) as f32 * 1e-2)
            .collect();
        let t = transfer(bands, 3, coeffs);
        let light = ShLight::constant(bands, [1.0, 0.5, 0.25]);
        relight(&t, &light).unwrap();
        let runs = 20;
        let started = Instant::now();
        for _ in 0..runs {
            std::hint::black_box(relight(&t, &light).unwrap());
        }
        println!(
            "relight {vertices} vertices, {bands} bands: {:.3} ms",
            started.elapsed().as_secs_f64() * 1e3 / runs as f64
        );
        let Some(ctx) = gpu_context() else { return };
        let scene = prepare(icosphere(Vec3::ZERO, 1.0, 6)).unwrap().0;
        let ones = vec![[1.0; 3]; scene.vertex_count()];
        let camera = Camera::framing_scene(&scene);
        render(ctx, &scene, &ones, &camera, 512, 512).unwrap();
        let started = Instant::now();
        for _ in 0..5 {
            std::hint::black_box(render(ctx, &scene, &ones, &camera, 512, 512).unwrap());
        }
        println!(
            "render 512x512, {} triangles on {}: {:.1} ms",
            scene.triangle_count(),
            ctx.adapter.label(),
            started.elapsed().as_secs_f64() * 1e3 / 5.0
        );
    }
}
