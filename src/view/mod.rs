//! `surftile view`: an endless, zoomable view of any source, in a window (winit + wgpu)
//! or headless.
//!
//! - **Sources** ([`SourceSpec`]): a bank (`.bank`), a milling configuration (`.toml`)
//!   or preset name, or a seed 001 model (`.toml`, or `rock`, `china`, `casting`,
//!   `cells-convex`, `cells-concave`), optionally under an imperfection layer
//!   (`--imperfect`). On a hardware GPU, banks are filled on the GPU every frame
//!   ([`GpuSurface`]). Milling models, and banks on a software adapter (where a frame
//!   costs ~100 ms), go through the [`PageStreamer`] with pages filled on the GPU (a
//!   zoomed-out milling frame can cost seconds); sources the GPU does not run (RSGF,
//!   Wang, seed 001 models, imperfection layers) go through it with pages filled on
//!   the CPU. The streamer's workers fill pages while the render loop draws what is
//!   resident (a coarser level, or grey, where a page is still coming): no frame waits
//!   for a page.
//! - **Display.** `shaders/shade.wgsl` draws the heights as a grey ramp (the source's
//!   mean ± 3σ, from a 256² sample at the origin) or Phong-shaded (seed 001,
//!   eqs. (1)–(4)) with the source's material (a model's, else the default). Colour
//!   banks (three channels, levels within [0, 65535]) show their colours in the
//!   height view, on the scale of their levels ([`crate::io::colour_full_scale`]:
//!   an 8-bit photo's 0–255 as black to full), and their first channel shaded.
//! - **Controls.** Drag or arrow keys pan; the wheel (or `+`/`-`) zooms about the
//!   cursor, through the mip levels; `s`/`S` next/previous seed; `h` height or shaded
//!   view; `l`/`k` light azimuth/elevation; `m` mask view (the layer ids of an
//!   imperfection layer, on a grey ramp from 0 to the highest id); `q` or Escape
//!   quits. The title shows the position, zoom, seed and frame time.
//! - **Scripts** ([`script::parse`]) drive the same moves for tests and frame-time
//!   measurements; `--screenshot` writes the last frame as an 8-bit RGBA PNG.

pub mod script;
mod window;

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use bytemuck::{Pod, Zeroable};

use crate::error::{Error, Result};
use crate::gpu::{Gpu, GpuSurface};
use crate::kinds::GpuFill;
use crate::stream::{Page, PageKey, PageStreamer, Region, Surface, View, default_threads};
use script::Step;

/// What the viewer shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// Heights as a grey ramp.
    Height,
    /// Phong-shaded relief.
    Shaded,
    /// The defect mask, for sources that have one.
    Mask,
}

/// Options of a viewer session.
#[derive(Clone, Debug)]
pub struct ViewOptions {
    /// Window (or headless frame) width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Placement seed.
    pub seed: u32,
    /// Surface pixel at the top-left corner.
    pub x: f64,
    /// Surface pixel at the top-left corner.
    pub y: f64,
    /// Surface pixels per screen pixel (1: full resolution; 16: zoomed out 16×).
    pub scale: f64,
    /// Pixel spacing of milling sources (µm).
    pub spacing_um: f64,
    /// Draw without a window.
    pub headless: bool,
    /// Frames to draw before exiting (default: the script's length plus one; endless in
    /// a window without a script).
    pub frames: Option<usize>,
    /// The scripted steps, one per frame.
    pub script: Vec<Step>,
    /// Where to write the last frame.
    pub screenshot: Option<PathBuf>,
    /// Byte budget of the page cache (CPU-only sources).
    pub cache_bytes: usize,
    /// Start in the shaded view.
    pub shaded: bool,
    /// Fill every frame of a bank on the GPU even on a software adapter (where banks
    /// otherwise go through GPU-filled pages).
    pub direct: bool,
    /// An imperfection layer over the source (a .toml or a preset): weathered heights,
    /// and the mask view shows its layer ids.
    pub imperfect: Option<PathBuf>,
    /// The imperfection layer's age (scales every γ).
    pub age: Option<f64>,
}

impl Default for ViewOptions {
    fn default() -> Self {
        ViewOptions {
            width: 800,
            height: 600,
            seed: 0,
            x: 0.0,
            y: 0.0,
            scale: 1.0,
            spacing_um: 6.1,
            headless: false,
            frames: None,
            script: Vec::new(),
            screenshot: None,
            cache_bytes: 256 << 20,
            shaded: false,
            direct: false,
            imperfect: None,
            age: None,
        }
    }
}

impl ViewOptions {
    /// Checks sizes and the starting view.
    pub fn validate(&self) -> Result<()> {
        for (name, v) in [("width", self.width), ("height", self.height)] {
            if !(16..=8192).contains(&v) {
                return Err(Error::param(name, v, "16 to 8192 pixels"));
            }
        }
        if !(self.scale.is_finite() && (1.0 / 64.0..=MAX_SCALE).contains(&self.scale)) {
            return Err(Error::param(
                "scale",
                self.scale,
                "surface pixels per screen pixel, from 1/64 to 2^24",
            ));
        }
        for (name, v) in [("x", self.x), ("y", self.y)] {
            if !(v.is_finite() && v.abs() <= MAX_POSITION) {
                return Err(Error::param(name, v, "a surface coordinate within ±1e15"));
            }
        }
        if !(self.spacing_um.is_finite() && self.spacing_um > 0.0) {
            return Err(Error::param(
                "spacing",
                self.spacing_um,
                "a positive µm value",
            ));
        }
        if self.cache_bytes < 16 << 20 {
            return Err(Error::param(
                "cache",
                format!("{} bytes", self.cache_bytes),
                "at least 16 MiB",
            ));
        }
        Ok(())
    }
}

/// Largest zoom-out: surface pixels per screen pixel.
const MAX_SCALE: f64 = (1u64 << 24) as f64;
/// Farthest the view's corner may go from the origin (surface pixels).
const MAX_POSITION: f64 = 1e15;
/// Page side of the streamer, in samples.
const PAGE: usize = 256;

/// A source as [`crate::open`] loads it.
pub use crate::front::Source as SourceSpec;

/// How a source's frames are filled.
enum Fill {
    Gpu(Box<GpuSurface>),
    Pages(PageStreamer),
}

/// An opened source: its CPU surface, how frames are filled, and its display scales.
pub struct Source {
    cpu: Arc<dyn Surface>,
    fill: Fill,
    range: (f32, f32),
    /// A colour source's full scale (see [`crate::io::colour_full_scale`]): the height
    /// view shows its colours.
    colour: Option<f32>,
    /// Slope exaggeration per surface pixel for the shaded view.
    exaggeration: f32,
    /// Weights of the shaded view (a model's material).
    material: crate::shade::ShadeOptions,
    /// An imperfection layer's id pages and its highest id.
    mask: Option<(PageStreamer, f32)>,
}

/// An imperfection layer's configuration and the folder of its relative paths.
pub type Layer = (crate::imperfect::ImperfectConfig, Option<PathBuf>);

impl Source {
    /// Opens `spec` under `seed`: on the GPU where it runs there, else through a page
    /// streamer of `cache_bytes`.
    pub fn open(
        spec: &SourceSpec,
        seed: u32,
        gpu: &Gpu,
        cache_bytes: usize,
        direct: bool,
        layer: Option<&Layer>,
    ) -> Result<Source> {
        // A milling frame can take longer than a frame's budget (zoomed out, every
        // sample averages up to 4 × 4 points over hundreds of rings), and on a software
        // adapter a full frame costs ~100 ms even for a bank: their pages are filled on
        // the GPU by the streamer's workers, on a device of their own, so the render
        // loop's queue never waits behind a page's dispatch.
        // RSGF and synth banks have no GPU twin: CPU pages.
        // Seed 001 models and imperfection layers have no GPU twin either.
        let gpu_fill = spec.kind().gpu();
        let on_gpu = layer.is_none() && !matches!(gpu_fill, GpuFill::Cpu(_));
        let milling = gpu_fill == GpuFill::Milling;
        let paged = milling || (gpu.info.device_type == wgpu::DeviceType::Cpu && !direct);
        let fill_gpu = if on_gpu && paged {
            Gpu::from_adapter(gpu.adapter.clone())?
        } else {
            gpu.clone()
        };
        // A milling source is built once (its `[adapt]` may read a measurement), for
        // the CPU twin and the GPU upload alike.
        let (cpu, gpu_surface): (Arc<dyn Surface>, Option<GpuSurface>) =
            match spec.loaded().milling(seed).transpose()? {
                Some(m) => {
                    let g = on_gpu
                        .then(|| GpuSurface::milling(&fill_gpu.device, m.clone()))
                        .transpose()?;
                    (Arc::new(m), g)
                }
                None => {
                    let (device, queue) = (&fill_gpu.device, &fill_gpu.queue);
                    let g = on_gpu
                        .then(|| GpuSurface::for_source(device, queue, spec.loaded(), seed))
                        .transpose()?;
                    (Arc::from(spec.loaded().surface(seed)?), g)
                }
            };
        let workers = default_threads().clamp(1, 16);
        // An imperfection layer over the surface: its heights and, for the mask view,
        // its layer ids, both through CPU pages.
        // (No GPU surface was made: `on_gpu` is false under a layer.)
        let (cpu, mask): (Arc<dyn Surface>, Option<(PageStreamer, f32)>) = match layer {
            None => (cpu, None),
            Some((config, base)) => {
                let imperfect = Arc::new(crate::imperfect::Imperfect::new(
                    cpu,
                    config,
                    base.as_deref(),
                    seed,
                )?);
                let ids = Arc::new(crate::imperfect::LayerIds(imperfect.clone()));
                let top = config.layers.thresholds.len().max(1) as f32;
                let pages = PageStreamer::new(ids, PAGE, workers, cache_bytes / 2)?;
                (imperfect, Some((pages, top)))
            }
        };
        let fill = match gpu_surface {
            Some(g) if paged => {
                let filled = Arc::new(crate::gpu::GpuFilled::from_parts(fill_gpu, g));
                Fill::Pages(PageStreamer::new(filled, PAGE, 2, cache_bytes)?)
            }
            Some(g) => Fill::Gpu(Box::new(g)),
            None => Fill::Pages(PageStreamer::new(cpu.clone(), PAGE, workers, cache_bytes)?),
        };
        let origin = crate::stream::OriginSample::of(cpu.as_ref())?;
        let (range, exaggeration) = scales_of(&origin);
        Ok(Source {
            // A colour source's full scale, from the levels of the same sample.
            colour: crate::io::colour_full_scale(cpu.channels(), origin.range.0, origin.range.1),
            cpu,
            fill,
            range,
            exaggeration,
            material: spec.material(),
            mask,
        })
    }

    /// Layer ids of `region` composed from resident mask pages (NaN where none is yet),
    /// for sources with an imperfection layer; `None` otherwise.
    pub fn mask(&self, region: &Region, out: &mut Vec<f32>) -> Option<bool> {
        let (pages, _) = self.mask.as_ref()?;
        out.clear();
        out.resize(region.len(), f32::NAN);
        Some(compose(pages, region, out))
    }

    /// The grey ramp's (black, white) heights.
    pub fn range(&self) -> (f32, f32) {
        self.range
    }

    /// The page streamer, when frames come from pages (RSGF, milling, banks on a
    /// software adapter).
    pub fn pages(&self) -> Option<&PageStreamer> {
        match &self.fill {
            Fill::Pages(p) => Some(p),
            Fill::Gpu(_) => None,
        }
    }

    /// A colour source's full scale, if it is one.
    pub fn colour(&self) -> Option<f32> {
        self.colour
    }

    /// Heights (channel 0) of `width × height` samples `step` apart from (x, y) into
    /// `out`, or with `colour` each sample's colour packed by [`pack_colour`]: from the
    /// GPU, or composed from resident pages (NaN where none is yet). Never waits for a
    /// page. Returns whether every sample came at full detail.
    pub fn heights(
        &self,
        gpu: &Gpu,
        region: &Region,
        out: &mut Vec<f32>,
        scratch: &mut Vec<f32>,
        colour: Option<f32>,
    ) -> Result<bool> {
        out.clear();
        out.resize(region.len(), f32::NAN);
        let c = self.cpu.channels();
        match &self.fill {
            Fill::Gpu(g) => {
                if c == 1 {
                    g.fill(&gpu.device, &gpu.queue, region, out)?;
                } else {
                    scratch.clear();
                    scratch.resize(region.len() * c, 0.0);
                    g.fill(&gpu.device, &gpu.queue, region, scratch)?;
                    for (o, s) in out.iter_mut().zip(scratch.chunks_exact(c)) {
                        *o = match colour {
                            Some(full) if c == 3 => pack_colour(s, full),
                            _ => s[0],
                        };
                    }
                }
                Ok(true)
            }
            Fill::Pages(p) => Ok(compose_colour(p, region, out, colour)),
        }
    }
}

/// The view of `region` for the page streamer.
fn page_view(region: &Region) -> View {
    View {
        x: region.x_at(0),
        y: region.y_at(0),
        width: region.width,
        height: region.height,
        scale: region.step,
    }
}

/// Fills `out` (channel 0 of `region`) from the pages resident in `pages`, asking for
/// the view's pages first. Nearest sample of the view's level, or of the nearest
/// coarser level resident; NaN where none is. True if every sample was at the view's
/// level.
pub fn compose(pages: &PageStreamer, region: &Region, out: &mut [f32]) -> bool {
    compose_colour(pages, region, out, None)
}

/// [`compose`], with `colour` (a three-channel source's full scale) each sample's
/// colour packed by [`pack_colour`] instead of channel 0.
pub fn compose_colour(
    pages: &PageStreamer,
    region: &Region,
    out: &mut [f32],
    colour: Option<f32>,
) -> bool {
    let view = page_view(region);
    pages.request(&view);
    let level = pages.level_for(&view);
    // Bands of rows on up to 8 threads (a 1080p frame is 2 M lookups).
    let threads = default_threads()
        .clamp(1, 8)
        .min(region.height.div_ceil(64));
    let band = region.height.div_ceil(threads.max(1)).max(1);
    std::thread::scope(|scope| {
        let jobs: Vec<_> = out
            .chunks_mut(band * region.width)
            .enumerate()
            .map(|(k, part)| {
                scope.spawn(move || compose_rows(pages, region, level, k * band, part, colour))
            })
            .collect();
        jobs.into_iter()
            .map(|j| j.join().expect("composition threads do not panic"))
            .fold(true, |a, b| a & b)
    })
}

/// [`compose`] for the rows from `r0` on that `out` holds, at page level `level`.
fn compose_rows(
    pages: &PageStreamer,
    region: &Region,
    level: u32,
    r0: usize,
    out: &mut [f32],
    colour: Option<f32>,
) -> bool {
    let size = pages.page_size() as i64;
    let mut found: HashMap<PageKey, Option<Arc<Page>>> = HashMap::new();
    let mut complete = true;
    let mut last: Option<(PageKey, Option<Arc<Page>>)> = None;
    let inv = 1.0 / (level as f64).exp2();
    for (r, row) in out.chunks_mut(region.width).enumerate() {
        let y = region.y_at(r0 + r);
        for (c, o) in row.iter_mut().enumerate() {
            let x = region.x_at(c);
            let (kx, ky) = ((x * inv).round() as i64, (y * inv).round() as i64);
            let key = PageKey {
                level,
                px: kx.div_euclid(size),
                py: ky.div_euclid(size),
            };
            // Neighbouring samples share a page: look it up once per run of them.
            if last.as_ref().is_none_or(|(k, _)| *k != key) {
                let page = found.entry(key).or_insert_with(|| pages.best(key)).clone();
                last = Some((key, page));
            }
            let Some((_, Some(page))) = &last else {
                *o = f32::NAN;
                complete = false;
                continue;
            };
            let (kx, ky) = if page.key.level == level {
                (kx, ky)
            } else {
                complete = false;
                let s = (page.key.level as f64).exp2();
                ((x / s).round() as i64, (y / s).round() as i64)
            };
            let lx = (kx - page.key.px * size).clamp(0, size - 1) as usize;
            let ly = (ky - page.key.py * size).clamp(0, size - 1) as usize;
            let at = (ly * page.size + lx) * page.channels;
            *o = match colour {
                Some(full) if page.channels == 3 => pack_colour(&page.data[at..at + 3], full),
                _ => page.data[at],
            };
        }
    }
    complete
}

/// A colour sample (three channels on the scale `full`) as 8-bit levels
/// r | g << 8 | b << 16 in the bits of an f32, for the height view of
/// `shaders/shade.wgsl` (mode 2, `unpack_colour`). The top byte is zero, so the bits are
/// never a NaN's, which marks a missing sample.
pub fn pack_colour(rgb: &[f32], full: f32) -> f32 {
    let level = |v: f32| ((v / full).clamp(0.0, 1.0) * 255.0).round() as u32;
    f32::from_bits(level(rgb[0]) | level(rgb[1]) << 8 | level(rgb[2]) << 16)
}

/// The grey ramp (mean ± 3σ) and the shading's slope exaggeration (rms slope 0.5 per
/// surface pixel, as `render --shade` picks it) of a surface, from a 256² sample at the
/// origin.
pub fn display_scales(s: &dyn Surface) -> Result<((f32, f32), f32)> {
    Ok(scales_of(&crate::stream::OriginSample::of(s)?))
}

/// [`display_scales`] from a sample already taken.
fn scales_of(o: &crate::stream::OriginSample) -> ((f32, f32), f32) {
    let half = if o.sd > 0.0 {
        3.0 * o.sd
    } else {
        o.mean.abs().max(1.0)
    };
    (
        ((o.mean - half) as f32, (o.mean + half) as f32),
        o.half_slope_scale() as f32,
    )
}

/// `shaders/shade.wgsl` `ShadeParams`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
struct ShadeParams {
    width: u32,
    height: u32,
    mode: u32,
    pad0: u32,
    lo: f32,
    hi: f32,
    exaggeration: f32,
    ambient: f32,
    light: [f32; 4],
    half: [f32; 4],
    diffuse: f32,
    specular: f32,
    shininess: f32,
    pad1: u32,
}
const _: () = assert!(std::mem::size_of::<ShadeParams>() == 80);

/// The format of the frame that screenshots read.
const FRAME_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;

/// Draws heights through `shaders/shade.wgsl` into an RGBA8 frame (and a window's
/// surface), and reads the frame back for screenshots.
pub struct Renderer {
    layout: wgpu::BindGroupLayout,
    pipelines: HashMap<wgpu::TextureFormat, wgpu::RenderPipeline>,
    shader: wgpu::ShaderModule,
    params: wgpu::Buffer,
    heights: wgpu::Buffer,
    frame: wgpu::Texture,
    width: u32,
    height: u32,
}

impl Renderer {
    /// A renderer of `width × height` frames.
    pub fn new(device: &wgpu::Device, width: u32, height: u32) -> Renderer {
        let shader = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("shade"),
            source: wgpu::ShaderSource::Wgsl(crate::gpu::module_source("shade").into()),
        });
        let entry = |binding, ty| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::FRAGMENT,
            ty: wgpu::BindingType::Buffer {
                ty,
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("shade"),
            entries: &[
                entry(0, wgpu::BufferBindingType::Uniform),
                entry(1, wgpu::BufferBindingType::Storage { read_only: true }),
            ],
        });
        let params = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("shade parameters"),
            size: std::mem::size_of::<ShadeParams>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let (heights, frame) = Self::targets(device, width, height);
        Renderer {
            layout,
            pipelines: HashMap::new(),
            shader,
            params,
            heights,
            frame,
            width,
            height,
        }
    }

    fn targets(device: &wgpu::Device, width: u32, height: u32) -> (wgpu::Buffer, wgpu::Texture) {
        let heights = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("view heights"),
            size: (width as u64 + 2) * (height as u64 + 2) * 4,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let frame = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("view frame"),
            size: wgpu::Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: FRAME_FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        (heights, frame)
    }

    /// Frame size in pixels.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// New frame size (a resized window).
    pub fn resize(&mut self, device: &wgpu::Device, width: u32, height: u32) {
        (self.heights, self.frame) = Self::targets(device, width, height);
        (self.width, self.height) = (width, height);
    }

    fn pipeline(&mut self, device: &wgpu::Device, format: wgpu::TextureFormat) {
        if self.pipelines.contains_key(&format) {
            return;
        }
        let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("shade"),
            bind_group_layouts: &[Some(&self.layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("shade"),
            layout: Some(&layout),
            vertex: wgpu::VertexState {
                module: &self.shader,
                entry_point: Some("vs_main"),
                compilation_options: Default::default(),
                buffers: &[],
            },
            primitive: Default::default(),
            depth_stencil: None,
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &self.shader,
                entry_point: Some("fs_main"),
                compilation_options: Default::default(),
                targets: &[Some(wgpu::ColorTargetState {
                    format,
                    blend: None,
                    write_mask: wgpu::ColorWrites::ALL,
                })],
            }),
            multiview_mask: None,
            cache: None,
        });
        self.pipelines.insert(format, pipeline);
    }

    /// Draws `heights` ((width + 2) × (height + 2), NaN for missing) with `params` into
    /// the frame, and into `surface` (a window's texture view and format) if given.
    fn draw(
        &mut self,
        gpu: &Gpu,
        heights: &[f32],
        params: &ShadeParams,
        surface: Option<(&wgpu::TextureView, wgpu::TextureFormat)>,
    ) {
        let device = &gpu.device;
        gpu.queue
            .write_buffer(&self.heights, 0, bytemuck::cast_slice(heights));
        gpu.queue
            .write_buffer(&self.params, 0, bytemuck::bytes_of(params));
        let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("shade"),
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: self.params.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: self.heights.as_entire_binding(),
                },
            ],
        });
        let frame_view = self.frame.create_view(&Default::default());
        let mut targets = vec![(&frame_view, FRAME_FORMAT)];
        if let Some(s) = surface {
            targets.push(s);
        }
        for (_, format) in &targets {
            self.pipeline(device, *format);
        }
        let mut encoder = device.create_command_encoder(&Default::default());
        for (view, format) in targets {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("shade"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: None,
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_pipeline(&self.pipelines[&format]);
            pass.set_bind_group(0, &bind, &[]);
            pass.draw(0..3, 0..1);
        }
        gpu.queue.submit([encoder.finish()]);
    }

    /// The last frame as RGBA8, row-major.
    pub fn read_frame(&self, gpu: &Gpu) -> Result<Vec<u8>> {
        let (w, h) = (self.width as usize, self.height as usize);
        let row = (w * 4).next_multiple_of(256);
        let buffer = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("screenshot"),
            size: (row * h) as u64,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        encoder.copy_texture_to_buffer(
            wgpu::TexelCopyTextureInfo {
                texture: &self.frame,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            wgpu::TexelCopyBufferInfo {
                buffer: &buffer,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(row as u32),
                    rows_per_image: None,
                },
            },
            wgpu::Extent3d {
                width: self.width,
                height: self.height,
                depth_or_array_layers: 1,
            },
        );
        gpu.queue.submit([encoder.finish()]);
        crate::gpu::read_mapped(&gpu.device, &buffer, "the frame", |data| {
            let mut out = Vec::with_capacity(w * h * 4);
            for r in 0..h {
                out.extend_from_slice(&data[r * row..r * row + w * 4]);
            }
            out
        })
    }
}

/// Frame-time statistics of a session (milliseconds).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FrameTimes {
    /// Every frame's time, in order.
    pub ms: Vec<f64>,
}

impl FrameTimes {
    /// (median, 95th percentile, max) in ms.
    pub fn summary(&self) -> (f64, f64, f64) {
        if self.ms.is_empty() {
            return (0.0, 0.0, 0.0);
        }
        let mut v = self.ms.clone();
        v.sort_by(f64::total_cmp);
        let at = |q: f64| v[((v.len() - 1) as f64 * q).round() as usize];
        (at(0.5), at(0.95), v[v.len() - 1])
    }
}

/// A viewer session without its window: the source, the camera, the script and the
/// renderer. Each [`Session::frame`] applies the next scripted step and draws.
pub struct Session {
    gpu: Gpu,
    spec: SourceSpec,
    /// The imperfection layer over the source, if any.
    layer: Option<Layer>,
    source: Source,
    renderer: Renderer,
    options: ViewOptions,
    /// Top-left sample (surface pixels) and surface pixels per screen pixel.
    x: f64,
    y: f64,
    scale: f64,
    seed: u32,
    mode: Mode,
    light: (f64, f64),
    step: usize,
    frames: usize,
    times: FrameTimes,
    heights: Vec<f32>,
    scratch: Vec<f32>,
    /// The last frame's status line (position, zoom, seed, pages).
    status: String,
    /// A notice for the title (e.g. no mask).
    notice: Option<String>,
    complete: bool,
}

impl Session {
    /// A session on `gpu` showing `spec`.
    pub fn new(gpu: Gpu, spec: SourceSpec, options: ViewOptions) -> Result<Session> {
        options.validate()?;
        if spec.imperfection().is_some() && options.scale < crate::imperfect::MIN_STEP {
            return Err(Error::param(
                "scale",
                options.scale,
                "at least 1/8 with an imperfection layer (a layer is computed down to 1/8 pixel)",
            ));
        }
        let layer = spec
            .imperfection()
            .map(|(c, base)| (c.clone(), base.map(Path::to_path_buf)));
        let source = Source::open(
            &spec,
            options.seed,
            &gpu,
            options.cache_bytes,
            options.direct,
            layer.as_ref(),
        )?;
        let renderer = Renderer::new(&gpu.device, options.width, options.height);
        // The material's light (225° azimuth, 45° up by default) as azimuth/elevation.
        let l = source.material.light.normalize().as_dvec3();
        let light = (
            l.y.atan2(l.x).to_degrees().rem_euclid(360.0),
            l.z.clamp(0.0, 1.0).asin().to_degrees(),
        );
        Ok(Session {
            gpu,
            spec,
            layer,
            source,
            renderer,
            x: options.x,
            y: options.y,
            scale: options.scale,
            seed: options.seed,
            mode: if options.shaded {
                Mode::Shaded
            } else {
                Mode::Height
            },
            light,
            step: 0,
            frames: 0,
            times: FrameTimes::default(),
            heights: Vec::new(),
            scratch: Vec::new(),
            status: String::new(),
            notice: None,
            complete: false,
            options,
        })
    }

    /// The device in use.
    pub fn gpu(&self) -> &Gpu {
        &self.gpu
    }

    /// The open source.
    pub fn source(&self) -> &Source {
        &self.source
    }

    /// The region the next frame shows: one sample per screen pixel, from the top-left.
    pub fn region(&self) -> Region {
        let (w, h) = self.renderer.size();
        Region::new(self.x, self.y, w as usize, h as usize).with_step(self.scale)
    }

    /// Frames drawn so far, and their times.
    pub fn frame_times(&self) -> &FrameTimes {
        &self.times
    }

    /// True once the script has run and the frame count is reached.
    pub fn finished(&self) -> bool {
        let want = self.options.frames.unwrap_or(
            if self.options.headless || !self.options.script.is_empty() {
                self.options.script.len() + 1
            } else {
                usize::MAX
            },
        );
        self.step >= self.options.script.len() && self.frames >= want
    }

    /// The title line: source state and the last frame's time.
    pub fn title(&self) -> String {
        let ms = self.times.ms.last().copied().unwrap_or(0.0);
        let mut t = format!("surftile view — {} — {ms:.1} ms", self.status);
        if let Some(n) = &self.notice {
            t.push_str(" — ");
            t.push_str(n);
        }
        t
    }

    /// Moves the view by (dx, dy) screen pixels.
    pub fn pan(&mut self, dx: f64, dy: f64) {
        let (x, y) = (self.x + dx * self.scale, self.y + dy * self.scale);
        if x.abs() <= MAX_POSITION && y.abs() <= MAX_POSITION {
            (self.x, self.y) = (x, y);
        } else {
            self.notice = Some("the edge of the coordinate range (±1e15 pixels)".into());
        }
    }

    /// Magnifies by `factor` about the screen point (cx, cy).
    pub fn zoom(&mut self, factor: f64, cx: f64, cy: f64) {
        // An imperfection layer is computed down to 1/8 pixel.
        let finest = if self.layer.is_some() {
            crate::imperfect::MIN_STEP
        } else {
            1.0 / 64.0
        };
        let mut scale = (self.scale / factor).clamp(finest, MAX_SCALE);
        // Zooms by powers of two in several steps land on the power exactly, where
        // pages' samples and mip levels line up with the screen's.
        let pow2 = scale.log2().round().exp2();
        if (scale - pow2).abs() <= 1e-9 * pow2 {
            scale = pow2;
        }
        let (px, py) = (self.x + cx * self.scale, self.y + cy * self.scale);
        let (x, y) = (px - cx * scale, py - cy * scale);
        if x.abs() <= MAX_POSITION && y.abs() <= MAX_POSITION {
            (self.x, self.y, self.scale) = (x, y, scale);
        }
    }

    /// Reopens the source under `seed`.
    pub fn set_seed(&mut self, seed: u32) -> Result<()> {
        self.source = Source::open(
            &self.spec,
            seed,
            &self.gpu,
            self.options.cache_bytes,
            self.options.direct,
            self.layer.as_ref(),
        )?;
        self.seed = seed;
        Ok(())
    }

    /// Switches the view mode; the mask view needs a source with a mask (an
    /// imperfection layer: `--imperfect`).
    pub fn show(&mut self, mode: Mode) {
        if mode == Mode::Mask && self.source.mask.is_none() {
            let notice = "this source has no mask (it needs an imperfection layer)";
            if self.options.headless {
                eprintln!("view: {notice}");
            }
            self.notice = Some(notice.into());
        } else {
            self.mode = mode;
            self.notice = None;
        }
    }

    /// Toggles between the height and the shaded view.
    pub fn toggle_shading(&mut self) {
        self.show(if self.mode == Mode::Height {
            Mode::Shaded
        } else {
            Mode::Height
        });
    }

    /// Light from `azimuth` and `elevation` (degrees).
    pub fn set_light(&mut self, azimuth: f64, elevation: f64) {
        self.light = (azimuth.rem_euclid(360.0), elevation.clamp(0.0, 90.0));
    }

    /// The light's (azimuth, elevation) in degrees.
    pub fn light(&self) -> (f64, f64) {
        self.light
    }

    /// The placement seed.
    pub fn seed(&self) -> u32 {
        self.seed
    }

    /// Applies the next scripted step, if any. Returns true when the step closes the
    /// window.
    pub fn script_step(&mut self) -> Result<bool> {
        let Some(step) = self.options.script.get(self.step).cloned() else {
            return Ok(false);
        };
        self.step += 1;
        let (w, h) = self.renderer.size();
        match step {
            Step::Pan(dx, dy) => self.pan(dx, dy),
            Step::Zoom(f) => self.zoom(f, w as f64 / 2.0, h as f64 / 2.0),
            Step::Wait => {}
            Step::Settle => {
                if let Some(p) = self.source.pages() {
                    let region = self.margin_region();
                    let view = page_view(&region);
                    p.request(&view);
                    while p.stats().pending > 0 {
                        std::thread::sleep(std::time::Duration::from_millis(5));
                    }
                }
            }
            Step::Seed(s) => self.set_seed(s)?,
            Step::Show(m) => self.show(m),
            Step::Light(a, e) => self.set_light(a, e),
            Step::Goto(x, y) => {
                (self.x, self.y) = (
                    x.clamp(-MAX_POSITION, MAX_POSITION),
                    y.clamp(-MAX_POSITION, MAX_POSITION),
                )
            }
            Step::Close => return Ok(true),
        }
        Ok(false)
    }

    /// The frame's samples with a one-sample margin for the shading's differences.
    fn margin_region(&self) -> Region {
        let (w, h) = self.renderer.size();
        Region::new(
            self.x - self.scale,
            self.y - self.scale,
            w as usize + 2,
            h as usize + 2,
        )
        .with_step(self.scale)
    }

    /// Draws a frame (into `surface` too, when given): heights from the GPU or the
    /// resident pages, then the shading pass. Never waits for a page.
    pub fn frame(
        &mut self,
        surface: Option<(&wgpu::TextureView, wgpu::TextureFormat)>,
    ) -> Result<()> {
        let start = Instant::now();
        let region = self.margin_region();
        let mask = (self.mode == Mode::Mask)
            .then(|| self.source.mask(&region, &mut self.heights))
            .flatten();
        self.complete = match mask {
            Some(complete) => complete,
            None => {
                let colour = self.source.colour.filter(|_| self.mode == Mode::Height);
                self.source.heights(
                    &self.gpu,
                    &region,
                    &mut self.heights,
                    &mut self.scratch,
                    colour,
                )?
            }
        };
        // The mask view: layer ids on a grey ramp from 0 (black) to the highest id.
        let (lo, hi) = match (&self.source.mask, self.mode) {
            (Some((_, top)), Mode::Mask) => (0.0, *top),
            _ => self.source.range,
        };
        let (w, h) = self.renderer.size();
        let (az, el) = (self.light.0.to_radians(), self.light.1.to_radians());
        let l = glam::Vec3::new(
            (el.cos() * az.cos()) as f32,
            (el.cos() * az.sin()) as f32,
            el.sin() as f32,
        )
        .normalize();
        let o = self.source.material;
        let half = crate::shade::half_vector(l, o.view.normalize());
        let params = ShadeParams {
            width: w,
            height: h,
            // 0 height (grey), 1 shaded, 2 colour (a colour source's height view).
            mode: match self.mode {
                Mode::Shaded => 1,
                Mode::Height if self.source.colour.is_some() => 2,
                _ => 0,
            },
            lo,
            hi,
            // Slopes come per sample, `scale` surface pixels apart.
            exaggeration: self.source.exaggeration / self.scale as f32,
            ambient: o.ambient,
            light: [l.x, l.y, l.z, 0.0],
            half: [half.x, half.y, half.z, 0.0],
            diffuse: o.diffuse,
            specular: o.specular,
            shininess: o.shininess,
            ..Default::default()
        };
        self.renderer
            .draw(&self.gpu, &self.heights, &params, surface);
        self.gpu
            .device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| Error::Gpu(format!("drawing a frame: {e}")))?;
        self.times.ms.push(start.elapsed().as_secs_f64() * 1e3);
        self.frames += 1;
        let pages = match self.source.pages() {
            Some(p) => {
                let s = p.stats();
                format!(", {} pages pending", s.pending)
            }
            None => String::new(),
        };
        self.status = format!(
            "x {:.0} y {:.0} zoom 1/{:.3} seed {}{pages}{}",
            self.x,
            self.y,
            self.scale,
            self.seed,
            if self.complete {
                ""
            } else {
                " (coarser levels shown)"
            }
        );
        Ok(())
    }

    /// Whether the last frame was drawn at full detail everywhere.
    pub fn complete(&self) -> bool {
        self.complete
    }

    /// Writes the last frame to the screenshot path, if one was given.
    pub fn screenshot(&self) -> Result<()> {
        let Some(path) = &self.options.screenshot else {
            return Ok(());
        };
        let (w, h) = self.renderer.size();
        let rgba = self.renderer.read_frame(&self.gpu)?;
        crate::io::write_png8(path, w as usize, h as usize, 4, &rgba)
    }

    /// One line: frames, frame-time median / 95th percentile / max, pages filled.
    pub fn summary(&self) -> String {
        let (med, p95, max) = self.times.summary();
        let pages = self
            .source
            .pages()
            .map(|p| {
                let s = p.stats();
                format!(
                    "; {} pages filled, {} cancelled, {} pending",
                    s.filled, s.cancelled, s.pending
                )
            })
            .unwrap_or_default();
        format!(
            "{} frames of {}×{}; frame time median {med:.1} ms, 95th percentile {p95:.1} ms, max {max:.1} ms{pages}",
            self.times.ms.len(),
            self.renderer.size().0,
            self.renderer.size().1
        )
    }
}

/// Runs a session: in a window, or headless (no display needed). Prints the
/// frame-time summary at the end and writes the screenshot, if asked.
pub fn run(source: &Path, options: ViewOptions) -> Result<()> {
    options.validate()?;
    let mut open = crate::Open::new(source).spacing_um(options.spacing_um);
    if let Some(path) = &options.imperfect {
        open = open.imperfection(path);
    }
    if let Some(age) = options.age {
        open = open.age(age);
    }
    let spec = open.open()?;
    if options.headless {
        let mut session = Session::new(Gpu::new()?, spec, options)?;
        eprintln!("view: drawing on {}", session.gpu().describe());
        while !session.finished() {
            if session.script_step()? {
                break;
            }
            session.frame(None)?;
        }
        session.screenshot()?;
        eprintln!("view: {}", session.summary());
        Ok(())
    } else {
        window::run(spec, options)
    }
}
