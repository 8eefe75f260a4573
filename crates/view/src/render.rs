//! The wgpu renderer: four pipelines of `shaders/view.wgsl` (opaque lit needle, translucent
//! lit tissue, markers, overlay), 4x multisampling, a 32-bit depth buffer, and the
//! offscreen path that copies the image into a buffer with rows padded to wgpu's 256-byte
//! alignment and reads it back.

use crate::camera::Camera;
use crate::colors;
use crate::frame::Frame;
use crate::geometry::{self, Vertex};
use crate::ViewError;
use glam::Vec3;
use std::path::Path;
use wgpu::util::DeviceExt;

/// The WGSL source of every pipeline.
pub const SHADER: &str = include_str!("../shaders/view.wgsl");

/// Largest image side accepted, pixels (a device may allow less:
/// [`Renderer::max_size`]).
pub const MAX_SIZE: u32 = 8192;

/// Samples per pixel of the multisampled colour and depth targets.
pub const SAMPLES: u32 = 4;

/// Format of the depth buffer.
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// Format of offscreen images.
pub const IMAGE_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;

/// Bytes of one row of a `width`-pixel RGBA8 image in a copy buffer: `4 * width` rounded
/// up to wgpu's `COPY_BYTES_PER_ROW_ALIGNMENT` (256).
pub fn padded_row_bytes(width: u32) -> u32 {
    let a = wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
    (4 * width).div_ceil(a) * a
}

/// Rejects an image with a side of 0 or above `max` ([`ViewError::BadSize`]).
pub fn check_size(width: u32, height: u32, max: u32) -> Result<(), ViewError> {
    if width == 0 || height == 0 || width > max || height > max {
        return Err(ViewError::BadSize { width, height, max });
    }
    Ok(())
}

/// An RGBA8 image, rows top to bottom, no padding.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Image {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// `4 * width * height` bytes, RGBA.
    pub rgba: Vec<u8>,
}

impl Image {
    /// The pixel at column `x`, row `y` (from the top).
    pub fn pixel(&self, x: u32, y: u32) -> [u8; 4] {
        let i = 4 * (y as usize * self.width as usize + x as usize);
        [
            self.rgba[i],
            self.rgba[i + 1],
            self.rgba[i + 2],
            self.rgba[i + 3],
        ]
    }

    /// Writes the image as an 8-bit RGBA PNG.
    pub fn save_png(&self, path: &Path) -> Result<(), ViewError> {
        let io = |source| ViewError::Io {
            path: path.to_path_buf(),
            source,
        };
        let png_err = |e: png::EncodingError| match e {
            png::EncodingError::IoError(source) => ViewError::Io {
                path: path.to_path_buf(),
                source,
            },
            other => ViewError::Png {
                path: path.to_path_buf(),
                message: other.to_string(),
            },
        };
        let file = std::fs::File::create(path).map_err(io)?;
        let mut encoder = png::Encoder::new(std::io::BufWriter::new(file), self.width, self.height);
        encoder.set_color(png::ColorType::Rgba);
        encoder.set_depth(png::BitDepth::Eight);
        let mut writer = encoder.write_header().map_err(png_err)?;
        writer.write_image_data(&self.rgba).map_err(png_err)?;
        writer.finish().map_err(png_err)
    }
}

/// The uniform block of the shader (`Globals`).
#[repr(C)]
#[derive(Debug, Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Globals {
    view_proj: [[f32; 4]; 4],
    eye: [f32; 4],
    light: [f32; 4],
    viewport: [f32; 4],
}

/// Multisampled colour and depth targets of one size.
struct Targets {
    width: u32,
    height: u32,
    color: wgpu::TextureView,
    depth: wgpu::TextureView,
}

/// Draws [`Frame`]s with wgpu on a device it is given (the simulation's, for example) or
/// one of its own.
pub struct Renderer {
    device: wgpu::Device,
    queue: wgpu::Queue,
    format: wgpu::TextureFormat,
    needle: wgpu::RenderPipeline,
    tissue: wgpu::RenderPipeline,
    markers: wgpu::RenderPipeline,
    overlay: wgpu::RenderPipeline,
    globals: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
    targets: Option<Targets>,
}

impl std::fmt::Debug for Renderer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Renderer")
            .field("format", &self.format)
            .finish_non_exhaustive()
    }
}

impl Renderer {
    /// A renderer of offscreen RGBA8 images on `device` (wgpu handles are shared, not
    /// copied: pass the simulation's `GpuContext` device to render on the same GPU).
    pub fn new(device: &wgpu::Device, queue: &wgpu::Queue) -> Renderer {
        Renderer::with_format(device, queue, IMAGE_FORMAT)
    }

    /// A renderer on the device of the GPU backend's context.
    pub fn from_gpu(ctx: &needlesim_gpu::GpuContext) -> Renderer {
        Renderer::new(&ctx.device, &ctx.queue)
    }

    /// A renderer into targets of `format` (a window surface's); `format` must be
    /// renderable with 4x multisampling (all 8-bit RGBA/BGRA formats are).
    pub fn with_format(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        format: wgpu::TextureFormat,
    ) -> Renderer {
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("needlesim-view"),
            source: wgpu::ShaderSource::Wgsl(SHADER.into()),
        });
        let layout_globals = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("view globals"),
            entries: &[wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
                count: None,
            }],
        });
        let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("view"),
            bind_group_layouts: &[Some(&layout_globals)],
            immediate_size: 0,
        });
        let globals = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("view globals"),
            size: std::mem::size_of::<Globals>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("view globals"),
            layout: &layout_globals,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: globals.as_entire_binding(),
            }],
        });
        let attributes = wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3, 2 => Float32x4];
        let pipeline = |label: &str,
                        vs: &str,
                        fs: &str,
                        blend: Option<wgpu::BlendState>,
                        depth_write: bool,
                        depth_compare: wgpu::CompareFunction| {
            device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some(label),
                layout: Some(&layout),
                vertex: wgpu::VertexState {
                    module: &module,
                    entry_point: Some(vs),
                    compilation_options: Default::default(),
                    buffers: &[Some(wgpu::VertexBufferLayout {
                        array_stride: std::mem::size_of::<Vertex>() as u64,
                        step_mode: wgpu::VertexStepMode::Vertex,
                        attributes: &attributes,
                    })],
                },
                primitive: wgpu::PrimitiveState {
                    topology: wgpu::PrimitiveTopology::TriangleList,
                    cull_mode: None,
                    ..Default::default()
                },
                depth_stencil: Some(wgpu::DepthStencilState {
                    format: DEPTH_FORMAT,
                    depth_write_enabled: Some(depth_write),
                    depth_compare: Some(depth_compare),
                    stencil: Default::default(),
                    bias: Default::default(),
                }),
                multisample: wgpu::MultisampleState {
                    count: SAMPLES,
                    ..Default::default()
                },
                fragment: Some(wgpu::FragmentState {
                    module: &module,
                    entry_point: Some(fs),
                    compilation_options: Default::default(),
                    targets: &[Some(wgpu::ColorTargetState {
                        format,
                        blend,
                        write_mask: wgpu::ColorWrites::ALL,
                    })],
                }),
                multiview_mask: None,
                cache: None,
            })
        };
        // Colour blended over what is behind, alpha accumulated to 1 (opaque images).
        let translucent = wgpu::BlendState {
            color: wgpu::BlendState::ALPHA_BLENDING.color,
            alpha: wgpu::BlendComponent::OVER,
        };
        use wgpu::CompareFunction::{Always, Less, LessEqual};
        Renderer {
            needle: pipeline("view needle", "vs_lit", "fs_lit", None, true, Less),
            tissue: pipeline(
                "view tissue",
                "vs_lit",
                "fs_lit",
                Some(translucent),
                false,
                LessEqual,
            ),
            markers: pipeline("view markers", "vs_marker", "fs_flat", None, false, Always),
            overlay: pipeline("view overlay", "vs_overlay", "fs_flat", None, false, Always),
            device: device.clone(),
            queue: queue.clone(),
            format,
            globals,
            bind_group,
            targets: None,
        }
    }

    /// A renderer on a device of its own: the high-performance adapter, no surface, the
    /// downlevel limits with textures up to the adapter's size (at most [`MAX_SIZE`]).
    pub fn headless() -> Result<Renderer, ViewError> {
        let (device, queue) = headless_device()?;
        Ok(Renderer::new(&device, &queue))
    }

    /// The device.
    pub fn device(&self) -> &wgpu::Device {
        &self.device
    }

    /// The queue.
    pub fn queue(&self) -> &wgpu::Queue {
        &self.queue
    }

    /// The format of the targets it draws into.
    pub fn format(&self) -> wgpu::TextureFormat {
        self.format
    }

    /// Largest image side: [`MAX_SIZE`] or the device's texture limit, the smaller.
    pub fn max_size(&self) -> u32 {
        MAX_SIZE.min(self.device.limits().max_texture_dimension_2d)
    }

    fn targets(&mut self, width: u32, height: u32) -> &Targets {
        let stale = self
            .targets
            .as_ref()
            .is_none_or(|t| t.width != width || t.height != height);
        if stale {
            let texture = |label, format| {
                self.device
                    .create_texture(&wgpu::TextureDescriptor {
                        label: Some(label),
                        size: wgpu::Extent3d {
                            width,
                            height,
                            depth_or_array_layers: 1,
                        },
                        mip_level_count: 1,
                        sample_count: SAMPLES,
                        dimension: wgpu::TextureDimension::D2,
                        format,
                        usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
                        view_formats: &[],
                    })
                    .create_view(&Default::default())
            };
            self.targets = Some(Targets {
                width,
                height,
                color: texture("view colour", self.format),
                depth: texture("view depth", DEPTH_FORMAT),
            });
        }
        self.targets.as_ref().expect("targets were just made")
    }

    /// Draws `frame` seen by `camera` into `target` (a single-sample view of
    /// [`Renderer::format`], `width` x `height` pixels: a surface texture or an offscreen
    /// texture) and submits the work. wgpu validation errors come back as
    /// [`ViewError::Render`].
    pub fn draw(
        &mut self,
        frame: &Frame,
        camera: &Camera,
        target: &wgpu::TextureView,
        width: u32,
        height: u32,
    ) -> Result<(), ViewError> {
        check_size(width, height, self.max_size())?;
        let scope = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let encoder = self.encode(frame, camera, target, width, height);
        self.queue.submit([encoder.finish()]);
        match pollster::block_on(scope.pop()) {
            Some(e) => Err(ViewError::Render(e.to_string())),
            None => Ok(()),
        }
    }

    fn encode(
        &mut self,
        frame: &Frame,
        camera: &Camera,
        target: &wgpu::TextureView,
        width: u32,
        height: u32,
    ) -> wgpu::CommandEncoder {
        let eye = camera.eye();
        let forward = (camera.target - eye).normalize_or(Vec3::NEG_Z);
        let right = forward.cross(Vec3::Z).normalize_or(Vec3::X);
        // A key light above, a little left of and behind the camera: it follows the orbit.
        let light = (-forward + 0.7 * Vec3::Z - 0.35 * right).normalize();
        let globals = Globals {
            view_proj: camera
                .view_proj(width as f32 / height as f32)
                .to_cols_array_2d(),
            eye: eye.extend(1.0).into(),
            light: light.extend(0.0).into(),
            viewport: [width as f32, height as f32, 0.0, 0.0],
        };
        self.queue
            .write_buffer(&self.globals, 0, bytemuck::bytes_of(&globals));

        let buffer = |device: &wgpu::Device, label: &str, data: &[u8], usage| {
            (!data.is_empty()).then(|| {
                device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some(label),
                    contents: data,
                    usage,
                })
            })
        };
        let vb = wgpu::BufferUsages::VERTEX;
        let needle = frame
            .needle
            .map(|(b, t)| geometry::needle(b, t, geometry::needle_radius(camera, height)))
            .unwrap_or_default();
        let (tissue, indices) = geometry::tissue(frame);
        let markers = geometry::markers(frame, geometry::marker_size(height));
        let plot = geometry::plot(frame, width, height);
        let d = &self.device;
        let needle_buf = buffer(d, "view needle", bytemuck::cast_slice(&needle), vb);
        let tissue_buf = buffer(d, "view tissue", bytemuck::cast_slice(&tissue), vb);
        let index_buf = buffer(
            d,
            "view tissue indices",
            bytemuck::cast_slice(&indices),
            wgpu::BufferUsages::INDEX,
        );
        let marker_buf = buffer(d, "view markers", bytemuck::cast_slice(&markers), vb);
        let plot_buf = buffer(d, "view plot", bytemuck::cast_slice(&plot), vb);

        let mut encoder = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("view frame"),
            });
        let bg = colors::rgba(colors::BACKGROUND, 1.0);
        let Renderer {
            needle: p_needle,
            tissue: p_tissue,
            markers: p_markers,
            overlay: p_overlay,
            bind_group,
            ..
        } = self;
        let (p_needle, p_tissue, p_markers, p_overlay, bind_group) = (
            p_needle.clone(),
            p_tissue.clone(),
            p_markers.clone(),
            p_overlay.clone(),
            bind_group.clone(),
        );
        let targets = self.targets(width, height);
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("view"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &targets.color,
                    depth_slice: None,
                    resolve_target: Some(target),
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color {
                            r: bg[0] as f64,
                            g: bg[1] as f64,
                            b: bg[2] as f64,
                            a: 1.0,
                        }),
                        store: wgpu::StoreOp::Discard,
                    },
                })],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &targets.depth,
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Clear(1.0),
                        store: wgpu::StoreOp::Discard,
                    }),
                    stencil_ops: None,
                }),
                ..Default::default()
            });
            pass.set_bind_group(0, &bind_group, &[]);
            if let Some(b) = &needle_buf {
                pass.set_pipeline(&p_needle);
                pass.set_vertex_buffer(0, b.slice(..));
                pass.draw(0..needle.len() as u32, 0..1);
            }
            if let (Some(v), Some(i)) = (&tissue_buf, &index_buf) {
                pass.set_pipeline(&p_tissue);
                pass.set_vertex_buffer(0, v.slice(..));
                pass.set_index_buffer(i.slice(..), wgpu::IndexFormat::Uint32);
                pass.draw_indexed(0..indices.len() as u32, 0, 0..1);
            }
            if let Some(b) = &marker_buf {
                pass.set_pipeline(&p_markers);
                pass.set_vertex_buffer(0, b.slice(..));
                pass.draw(0..markers.len() as u32, 0..1);
            }
            if let Some(b) = &plot_buf {
                pass.set_pipeline(&p_overlay);
                pass.set_vertex_buffer(0, b.slice(..));
                pass.draw(0..plot.len() as u32, 0..1);
            }
        }
        encoder
    }

    /// Renders `frame` offscreen at `width` x `height` and reads the pixels back.
    pub fn render_to_image(
        &mut self,
        frame: &Frame,
        camera: &Camera,
        width: u32,
        height: u32,
    ) -> Result<Image, ViewError> {
        check_size(width, height, self.max_size())?;
        let scope = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let size = wgpu::Extent3d {
            width,
            height,
            depth_or_array_layers: 1,
        };
        let texture = self.device.create_texture(&wgpu::TextureDescriptor {
            label: Some("view image"),
            size,
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: self.format,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        let view = texture.create_view(&Default::default());
        let row = padded_row_bytes(width);
        let readback = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("view readback"),
            size: row as u64 * height as u64,
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        let mut encoder = self.encode(frame, camera, &view, width, height);
        encoder.copy_texture_to_buffer(
            wgpu::TexelCopyTextureInfo {
                texture: &texture,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            wgpu::TexelCopyBufferInfo {
                buffer: &readback,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(row),
                    rows_per_image: Some(height),
                },
            },
            size,
        );
        self.queue.submit([encoder.finish()]);
        if let Some(e) = pollster::block_on(scope.pop()) {
            return Err(ViewError::Render(e.to_string()));
        }
        let padded = read_buffer(&self.device, &readback)?;
        let bgra = matches!(
            self.format,
            wgpu::TextureFormat::Bgra8Unorm | wgpu::TextureFormat::Bgra8UnormSrgb
        );
        Ok(Image {
            width,
            height,
            rgba: unpad_rows(&padded, width, height, row, bgra),
        })
    }
}

/// Maps `buffer` for reading, waits, and copies it out.
fn read_buffer(device: &wgpu::Device, buffer: &wgpu::Buffer) -> Result<Vec<u8>, ViewError> {
    let slice = buffer.slice(..);
    let (tx, rx) = std::sync::mpsc::channel();
    slice.map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| ViewError::Readback(e.to_string()))?;
    rx.recv()
        .map_err(|_| ViewError::Readback("the map callback never ran".into()))?
        .map_err(|e| ViewError::Readback(e.to_string()))?;
    let data = slice
        .get_mapped_range()
        .map_err(|e| ViewError::Readback(e.to_string()))?
        .to_vec();
    buffer.unmap();
    Ok(data)
}

/// The `width * 4` image bytes of each of `height` rows of `row` bytes, with the blue and
/// red channels swapped when `bgra`.
pub fn unpad_rows(padded: &[u8], width: u32, height: u32, row: u32, bgra: bool) -> Vec<u8> {
    let tight = 4 * width as usize;
    let mut out = Vec::with_capacity(tight * height as usize);
    for r in padded.chunks(row as usize).take(height as usize) {
        out.extend_from_slice(&r[..tight]);
    }
    if bgra {
        out.chunks_exact_mut(4).for_each(|p| p.swap(0, 2));
    }
    out
}

/// A device and queue of its own for offscreen rendering (no surface): what
/// [`Renderer::headless`] uses.
pub fn headless_device() -> Result<(wgpu::Device, wgpu::Queue), ViewError> {
    let instance =
        wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
    request_device(&instance, None)
}

/// Requests a device on the high-performance adapter (one that can present to `surface`
/// when given).
pub(crate) fn request_device(
    instance: &wgpu::Instance,
    surface: Option<&wgpu::Surface<'_>>,
) -> Result<(wgpu::Device, wgpu::Queue), ViewError> {
    device_on(&request_adapter(instance, surface)?)
}

/// A device on `adapter` with the downlevel limits and textures as large as the adapter
/// allows up to [`MAX_SIZE`].
pub(crate) fn device_on(adapter: &wgpu::Adapter) -> Result<(wgpu::Device, wgpu::Queue), ViewError> {
    let info = adapter.get_info();
    pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        label: Some("needlesim-view"),
        required_limits: view_limits(adapter),
        ..Default::default()
    }))
    .map_err(|e| ViewError::Device {
        adapter: info.name.clone(),
        message: e.to_string(),
    })
}

/// What drawing needs of a device on `adapter`: the downlevel limits, with textures as
/// large as the adapter allows up to [`MAX_SIZE`].
pub(crate) fn view_limits(adapter: &wgpu::Adapter) -> wgpu::Limits {
    wgpu::Limits {
        max_texture_dimension_2d: adapter.limits().max_texture_dimension_2d.min(MAX_SIZE),
        ..wgpu::Limits::downlevel_defaults()
    }
}

/// The high-performance adapter, compatible with `surface` when given.
pub(crate) fn request_adapter(
    instance: &wgpu::Instance,
    surface: Option<&wgpu::Surface<'_>>,
) -> Result<wgpu::Adapter, ViewError> {
    pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
        power_preference: wgpu::PowerPreference::HighPerformance,
        force_fallback_adapter: false,
        compatible_surface: surface,
        ..Default::default()
    }))
    .map_err(|e| ViewError::NoAdapter(e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_are_padded_to_256_bytes() {
        assert_eq!(padded_row_bytes(1), 256);
        assert_eq!(padded_row_bytes(37), 256);
        assert_eq!(padded_row_bytes(64), 256);
        assert_eq!(padded_row_bytes(65), 512);
        let (w, h, row) = (3u32, 2u32, 256u32);
        let mut padded = vec![0u8; (row * h) as usize];
        for y in 0..h {
            for x in 0..4 * w {
                padded[(y * row + x) as usize] = (10 * y + x) as u8;
            }
        }
        let out = unpad_rows(&padded, w, h, row, false);
        assert_eq!(out.len(), 24);
        assert_eq!(&out[12..16], &[10, 11, 12, 13]);
        let swapped = unpad_rows(&padded, w, h, row, true);
        assert_eq!(&swapped[0..4], &[2, 1, 0, 3]);
    }

    /// `view.wgsl` parses and validates with naga, and has every entry point the
    /// pipelines name, of the right stage.
    #[test]
    fn the_shader_validates_and_has_the_pipelines_entry_points() {
        let module = naga::front::wgsl::parse_str(SHADER)
            .unwrap_or_else(|e| panic!("{}", e.emit_to_string(SHADER)));
        naga::valid::Validator::new(
            naga::valid::ValidationFlags::all(),
            naga::valid::Capabilities::default(),
        )
        .validate(&module)
        .unwrap_or_else(|e| panic!("{e:?}"));
        let stage = |name: &str| {
            module
                .entry_points
                .iter()
                .find(|e| e.name == name)
                .map(|e| e.stage)
        };
        for vs in ["vs_lit", "vs_marker", "vs_overlay"] {
            assert_eq!(stage(vs), Some(naga::ShaderStage::Vertex), "{vs}");
        }
        for fs in ["fs_lit", "fs_flat"] {
            assert_eq!(stage(fs), Some(naga::ShaderStage::Fragment), "{fs}");
        }
    }

    #[test]
    fn sizes_out_of_range_are_rejected() {
        assert!(matches!(
            check_size(0, 10, MAX_SIZE),
            Err(ViewError::BadSize { width: 0, .. })
        ));
        assert!(check_size(10, MAX_SIZE + 1, MAX_SIZE).is_err());
        assert!(check_size(MAX_SIZE, 1, MAX_SIZE).is_ok());
    }
}
