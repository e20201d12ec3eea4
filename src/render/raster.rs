//! The raster pipeline: a relit mesh drawn headlessly into a float colour target on any
//! wgpu adapter, and read back as linear HDR RGBA.

use glam::Vec3;
use wgpu::util::DeviceExt;

use super::camera::{bounds, usable_radius, Camera};
use super::relight::{relight, relight_baked};
use crate::bake::split::split_scene_corners;
use crate::bake::texels::sample_bilinear;
use crate::bake::{BakedMesh, TexelBake, Transfer};
use crate::device::GpuContext;
use crate::error::{Error, Result};
use crate::light::ShLight;
use crate::lightmap::TexelRows;
use crate::scene::Scene;
use crate::shaders;

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
                    .map(|b| half::f16::from_bits(u16::from_ne_bytes([b[0], b[1]])).to_f32()),
            ),
        };
        let mut lanes = lanes.fuse();
        std::iter::from_fn(move || {
            Some([lanes.next()?, lanes.next()?, lanes.next()?, lanes.next()?])
        })
    }
}

/// A baked mesh relit under `light` and rendered from `camera` (framed automatically when
/// `None`): linear HDR RGBA, row 0 at the top.
pub fn preview(
    ctx: &GpuContext,
    baked: &BakedMesh,
    light: &ShLight,
    camera: Option<&Camera>,
    width: u32,
    height: u32,
) -> Result<Vec<[f32; 4]>> {
    let framed = Camera::framing_scene(&baked.scene);
    let camera = camera.unwrap_or(&framed);
    match &baked.lightmap {
        None => {
            let radiance = relight_baked(baked, light)?;
            render(ctx, &baked.scene, &radiance, camera, width, height)
        }
        Some(texels) => render_texels(ctx, &baked.scene, texels, light, camera, width, height),
    }
}

/// Every texel of `texels` relit by `light`, RGB: those of a held lightmap read back a block of
/// rows at a time.
fn relit_texels(texels: &TexelBake, light: &ShLight) -> Result<Vec<f32>> {
    let Some(held) = &texels.held else {
        return Ok(relight(&texels.transfer, light)?
            .into_iter()
            .flatten()
            .collect());
    };
    const ROWS: usize = 64;
    let shape = held.shape();
    let mut relit = Vec::with_capacity(shape.width as usize * shape.height as usize * 3);
    for first in (0..shape.height as usize).step_by(ROWS) {
        let rows = first..(first + ROWS).min(shape.height as usize);
        let texel_count = rows.len() * shape.width as usize;
        let values = held.read_rows(rows)?.into_owned();
        let block = Transfer::new(shape.bands, shape.channels, texel_count, values)
            .expect("whole rows of the held map's shape");
        relit.extend(relight(&block, light)?.into_iter().flatten());
    }
    Ok(relit)
}

/// A lightmapped mesh: the texels relit, then looked up bilinearly at each pixel's lightmap
/// coordinates (rasterised as the "radiance" of a first pass, interpolated perspective-correct
/// as any vertex attribute), as a renderer samples a lightmap texture.
fn render_texels(
    ctx: &GpuContext,
    scene: &Scene,
    texels: &TexelBake,
    light: &ShLight,
    camera: &Camera,
    width: u32,
    height: u32,
) -> Result<Vec<[f32; 4]>> {
    let relit = relit_texels(texels, light)?;
    let coordinates: Vec<[f32; 3]> = texels.texcoords.iter().map(|&[u, v]| [u, v, 0.0]).collect();
    // The coordinates are per triangle corner: a scene that shares vertices between corners (a
    // glTF scene's own UV set, a mesh split only where its charts meet) is drawn split at its
    // corners to carry them. One split already stays as it is.
    let split;
    let already_split = (0..scene.triangles.len() as u32)
        .zip(&scene.triangles)
        .all(|(t, corners)| *corners == [3 * t, 3 * t + 1, 3 * t + 2]);
    let scene = match already_split && scene.vertex_count() == coordinates.len() {
        true => scene,
        false => {
            split = split_scene_corners(scene);
            &split
        }
    };
    let mut pixels = render(ctx, scene, &coordinates, camera, width, height)?;
    for pixel in pixels.iter_mut().filter(|p| p[3] > 0.0) {
        let rgb = sample_bilinear(&relit, 3, texels.width, texels.height, [pixel[0], pixel[1]]);
        *pixel = [rgb[0], rgb[1], rgb[2], pixel[3]];
    }
    Ok(pixels)
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
    let bind_group = ctx.bind_buffers("render", &pipeline.get_bind_group_layout(0), &[&uniform]);
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

/// The preview's render pipeline, its bind-group layout derived from the WGSL.
fn pipeline(device: &wgpu::Device, color_format: wgpu::TextureFormat) -> wgpu::RenderPipeline {
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("render"),
        source: wgpu::ShaderSource::Wgsl(shaders::render_shader().into()),
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
        layout: None,
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::device;
    use crate::render::test_support::transfer;
    use crate::render::{write_image, ToneMap};
    use crate::scene::builtin::icosphere;
    use crate::scene::prepare::prepare;
    use crate::testing::entries;
    use std::sync::OnceLock;
    use std::time::Instant;

    /// The device for GPU tests, or `None` (reason printed) where there is no adapter outside
    /// CI; under CI a missing adapter fails, as in tests/common.
    fn gpu_context() -> Option<&'static GpuContext> {
        static GPU: OnceLock<Option<GpuContext>> = OnceLock::new();
        GPU.get_or_init(device::any_adapter_or_skip).as_ref()
    }

    fn unit_sphere(center: Vec3) -> Scene {
        prepare(icosphere(center, 1.0, 4)).unwrap().0
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

    /// One half float through the read-back's decoder (the first lane of a texel).
    fn decode_half(bits: u16) -> f32 {
        let texel = [bits, 0, 0, 0];
        let mut pixels = ColorFormat::Rgba16Float.decode(bytemuck::cast_slice(&texel));
        pixels.next().unwrap()[0]
    }

    #[test]
    fn half_floats_decode_exactly() {
        assert_eq!(decode_half(0x0000), 0.0);
        assert_eq!(decode_half(0x3c00), 1.0);
        assert_eq!(decode_half(0x3555), 0.333_251_95);
        assert_eq!(decode_half(0x7bff), 65504.0);
        assert_eq!(decode_half(0x0001), 2f32.powi(-24));
        assert_eq!(decode_half(0x03ff), 1023.0 * 2f32.powi(-24));
        assert_eq!(decode_half(0xfc00), f32::NEG_INFINITY);
        assert!(decode_half(0x7e00).is_nan());
        assert!(decode_half(0x8000).is_sign_negative());
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
        let scratch = tempfile::tempdir().unwrap();
        let scene = unit_sphere(Vec3::ZERO);
        let ones = vec![[1.0; 3]; scene.vertex_count()];
        let camera = Camera::framing_scene(&scene);
        let size = 128;
        let image = render(ctx, &scene, &ones, &camera, size, size).unwrap();
        let coverage = image.iter().filter(|p| p[3] > 0.0).count() as f64 / image.len() as f64;
        let path = scratch.path().join("sphere.png");
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
        assert_eq!(entries(scratch.path()), ["sphere.png"]);
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
    #[ignore = "timing: cargo test --release --lib render::raster::tests::timing -- --ignored --nocapture"]
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
