//! Region fills on the GPU from a bank (`shaders/toroidal.wgsl`, `shaders/blend.wgsl`),
//! and the hash check behind the parity tests (`shaders/hash_check.wgsl`).
//!
//! # Precision far from the origin
//! No f32 on the GPU ever holds an absolute coordinate. The host computes each column's
//! and row's coordinate in f64, exactly as the CPU fill does ([`Region::x_at`]), and
//! passes it as an integer offset from the region's origin texel plus an f32 fraction
//! (`Axis` in `shaders/axis.wgsl`); the origin's cell goes once, as two 32-bit words of
//! its i64. A region at |x| ≈ 10⁸ (or 10¹⁵) is as exact as one at the origin, and its
//! cells hash to the CPU's bits.

use bytemuck::{Pod, Zeroable};
use wgpu::util::DeviceExt;

use super::helpers::{
    BandFill, GROUP, MAX_BAND_BYTES, band_limit, bytes, check_scope, dispatch_and_read,
    dispatch_fill, entry, pipeline, storage, too_big, uniform, upload,
};
use super::milling::GpuMilling;
use crate::bank::Bank;
use crate::error::{Error, Result};
use crate::kinds::{GpuFill, Loaded};
use crate::models::milling::MillingSurface;
use crate::stream::blend::BlendSurface;
use crate::stream::toroidal::ToroidalSurface;
use crate::stream::{Region, Surface, check_buffer, mip_level};

/// `shaders/axis.wgsl` `Axis`: a column's or row's split coordinates.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
struct Axis {
    d: i32,
    f: f32,
    ui: i32,
    uf: f32,
    vi: i32,
    vf: f32,
    pad: [u32; 2],
}

/// `shaders/toroidal.wgsl` `TorAxis`: a column's or row's texel offset and fraction,
/// and the changes of its rhomboid numerators as quotient and remainder by det.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
struct TorAxis {
    d: i32,
    f: f32,
    sq: i32,
    sr: i32,
    tq: i32,
    tr: i32,
    pad: [u32; 2],
}

/// `shaders/toroidal.wgsl` `TorLevel`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
struct TorLevel {
    a: i32,
    b: i32,
    c: i32,
    tile_stride: u32,
    texel_base: u32,
    lx0: i32,
    ly0: i32,
    rs0: i32,
    i0: [u32; 2],
    j0: [u32; 2],
    s0: [u32; 2],
    t0: [u32; 2],
    ds_x: i32,
    dt_x: i32,
    ds_y: i32,
    dt_y: i32,
    rt0: i32,
    pad: [u32; 3],
}

/// `shaders/toroidal.wgsl` `TorParams`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
struct TorParams {
    width: u32,
    height: u32,
    channels: u32,
    tiles: u32,
    seed: u32,
    det: i32,
    t: f32,
    colours: u32,
    level: [TorLevel; 2],
}

/// `shaders/blend.wgsl` `BlendLevel`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
struct BlendLevel {
    w: u32,
    h: u32,
    tile_stride: u32,
    texel_base: u32,
    lut_base: u32,
    pad0: u32,
    scale: f32,
    centre: f32,
    mean: [f32; 4],
    lut_scale: [f32; 4],
}

/// `shaders/blend.wgsl` `BlendParams`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
struct BlendParams {
    width: u32,
    height: u32,
    channels: u32,
    tiles: u32,
    seed: u32,
    tile_shift: u32,
    lut_size: u32,
    pad0: u32,
    t: f32,
    lut_last: f32,
    lut_centre: f32,
    pad1: u32,
    mask_x: u32,
    mask_y: u32,
    xm0: u32,
    ym0: u32,
    bx0: [u32; 2],
    by0: [u32; 2],
    level: [BlendLevel; 2],
}

// The WGSL layouts (uniform arrays of 16-byte-aligned structs).
const _: () = assert!(std::mem::size_of::<Axis>() == 32);
const _: () = assert!(std::mem::size_of::<TorAxis>() == 32);
const _: () = assert!(std::mem::size_of::<TorLevel>() == 96);
const _: () = assert!(std::mem::size_of::<TorParams>() == 224);
const _: () = assert!(std::mem::size_of::<BlendLevel>() == 64);
const _: () = assert!(std::mem::size_of::<BlendParams>() == 208);

/// An i64 as the (low, high) words WGSL carries it in.
fn words(i: i64) -> [u32; 2] {
    [i as u32, (i >> 32) as u32]
}

/// ⌊v⌋ of a finite f64 whose floor fits an i64.
fn floor_i(v: f64) -> i64 {
    v.floor() as i64
}

/// v split into its integer part relative to `base` (which must fit an i32) and its
/// fraction as f32.
fn rel(v: f64, base: i64, what: &str) -> Result<(i32, f32)> {
    let i = floor_i(v);
    let d = i32::try_from(i.wrapping_sub(base)).map_err(|_| {
        Error::Limits(format!(
            "{what} spans more than 2^31 texels; fill it on the GPU in smaller regions"
        ))
    })?;
    Ok((d, (v - i as f64) as f32))
}

/// The rule a GPU surface runs, with its constant data.
enum Kind {
    Toroidal(ToroidalSurface),
    Blend(BlendSurface),
}

/// A bank's texels (and tables) on the GPU, with its rule's pipeline.
struct BankGpu {
    kind: Kind,
    channels: usize,
    levels: usize,
    /// Start of each level in the texel buffer (and, for the blend rule, the table buffer).
    texel_base: Vec<u32>,
    lut_base: Vec<u32>,
    texels: wgpu::Buffer,
    luts: Option<wgpu::Buffer>,
    pipeline: wgpu::ComputePipeline,
}

/// A surface on the GPU: a bank's texels (and tables) as storage buffers, or a
/// milling model's tables, with the pipeline of its rule and the placement seed. Fills
/// any region, as [`crate::stream::Surface::fill`] does on the CPU.
pub struct GpuSurface {
    backing: Box<dyn BandFill>,
    channels: usize,
    max_band_bytes: u64,
}

impl GpuSurface {
    /// Uploads what `source` needs for fills placed with `seed`, as its kind's
    /// [`GpuFill`] says; a kind without a GPU twin is refused with
    /// [`Error::Unsupported`] (callers fall back to the CPU).
    pub fn for_source(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        source: &dyn Loaded,
        seed: u32,
    ) -> Result<GpuSurface> {
        if let Some(bank) = source.bank() {
            return GpuSurface::new(device, queue, bank, seed);
        }
        match source.milling(seed) {
            Some(milling) => GpuSurface::milling(device, milling?),
            None => Err(unsupported(source.kind().name(), source.kind().gpu())),
        }
    }

    /// Uploads `bank` for fills placed with `seed`, as its kind's [`GpuFill`] says:
    /// blend, toroidal and milling banks run on the GPU; the others are refused with
    /// [`Error::Unsupported`] (callers fall back to the CPU).
    pub fn new(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        bank: &Bank,
        seed: u32,
    ) -> Result<GpuSurface> {
        let fill = crate::kinds::of_bank(bank).gpu();
        let (kind, module, entry) = match fill {
            GpuFill::Milling => {
                return GpuSurface::milling(device, MillingSurface::from_bank(bank, seed)?);
            }
            GpuFill::Toroidal => (
                Kind::Toroidal(ToroidalSurface::new(bank, seed)?),
                "toroidal",
                "fill_toroidal",
            ),
            GpuFill::Blend => (
                Kind::Blend(BlendSurface::new(bank, seed)?),
                "blend",
                "fill_blend",
            ),
            GpuFill::Cpu(_) => {
                return Err(unsupported(&bank.header.rule().to_string(), fill));
            }
        };
        let limit = band_limit(device);
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let levels: Vec<&[u8]> = bank
            .texels
            .iter()
            .map(|t| bytemuck::cast_slice(t))
            .collect();
        let (texels, texel_base) = upload(device, queue, "bank texels", &levels, 4, limit)?;
        let (luts, lut_base) = match &kind {
            Kind::Blend(s) => {
                let tables: Vec<&[u8]> = s
                    .levels
                    .iter()
                    .map(|l| bytemuck::cast_slice(&l.lut))
                    .collect();
                let (buffer, base) = upload(device, queue, "bank tables", &tables, 8, limit)?;
                (Some(buffer), base)
            }
            Kind::Toroidal(_) => (None, Vec::new()),
        };
        let pipeline = pipeline(device, module, entry);
        check_scope(scope, "uploading the bank")?;
        Ok(GpuSurface {
            backing: Box::new(BankGpu {
                channels: bank.header.channels,
                levels: bank.header.levels.len(),
                kind,
                texel_base,
                lut_base,
                texels,
                luts,
                pipeline,
            }),
            channels: bank.header.channels,
            max_band_bytes: limit.min(MAX_BAND_BYTES),
        })
    }

    /// A milling surface on the GPU (`shaders/milling.wgsl`): its tables uploaded once;
    /// each fill's ring lists are found on the host (see `gpu::milling`).
    pub fn milling(device: &wgpu::Device, surface: MillingSurface) -> Result<GpuSurface> {
        Ok(GpuSurface {
            backing: Box::new(GpuMilling::new(device, surface)?),
            channels: 1,
            max_band_bytes: band_limit(device).min(MAX_BAND_BYTES),
        })
    }

    /// Values per sample.
    pub fn channels(&self) -> usize {
        self.channels
    }

    /// The CPU twin of this surface (same bank and seed), for single samples.
    pub fn cpu(&self) -> &dyn Surface {
        self.backing.cpu()
    }

    /// Samples the host computed in f64 because the GPU could not decide them in f32
    /// (milling pixels at a ring's part border), over every fill so far; 0 for banks.
    pub fn host_recomputed(&self) -> u64 {
        self.backing.host_recomputed()
    }

    /// Fills `region` into `out` (row-major, interleaved channels), as the CPU's
    /// [`crate::stream::Surface::fill`] does: the same texels, hashes and weights, within 1e-5 relative
    /// error. Large regions go in bands of rows.
    pub fn fill(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        region: &Region,
        out: &mut [f32],
    ) -> Result<()> {
        region.validate()?;
        check_buffer(region, self.channels, out)?;
        if region.width > (u16::MAX as usize) * GROUP as usize {
            return Err(Error::Limits(format!(
                "a region {} samples wide on the GPU (at most {}); fill it in narrower pieces",
                region.width,
                u16::MAX as u32 * GROUP
            )));
        }
        let row_bytes = (region.width * self.channels * 4) as u64;
        let band = ((self.max_band_bytes / row_bytes) as usize)
            .clamp(1, u16::MAX as usize * GROUP as usize);
        let row_len = region.width * self.channels;
        for (k, chunk) in out.chunks_mut(band * row_len).enumerate() {
            let rows = chunk.len() / row_len;
            let sub = region.sub(0, k * band, region.width, rows)?;
            self.backing.fill_band(device, queue, &sub, chunk)?;
        }
        Ok(())
    }
}

impl BandFill for BankGpu {
    fn cpu(&self) -> &dyn Surface {
        match &self.kind {
            Kind::Toroidal(s) => s,
            Kind::Blend(s) => s,
        }
    }

    fn fill_band(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        region: &Region,
        out: &mut [f32],
    ) -> Result<()> {
        self.dispatch(device, queue, region, out)
    }
}

impl BankGpu {
    /// One dispatch: parameters and axes for `region`, then the read-back.
    fn dispatch(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        region: &Region,
        out: &mut [f32],
    ) -> Result<()> {
        let (l0, t) = mip_level(region.step, self.levels);
        let l1 = (l0 + 1).min(self.levels - 1);
        let (params, cols, rows): (Vec<u8>, Vec<u8>, Vec<u8>) = match &self.kind {
            Kind::Toroidal(s) => {
                let (p, c, r) = self.toroidal_params(s, region, [l0, l1], t)?;
                (bytes(&[p]), bytes(&c), bytes(&r))
            }
            Kind::Blend(s) => {
                let (p, c, r) = self.blend_params(s, region, [l0, l1], t)?;
                (bytes(&[p]), bytes(&c), bytes(&r))
            }
        };
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let uniform = uniform(device, &params);
        let (cols, rows) = (
            storage(device, "surftile columns", &cols),
            storage(device, "surftile rows", &rows),
        );
        let bytes = std::mem::size_of_val(out) as u64;
        let target = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("surftile fill"),
            size: bytes,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let mut entries = vec![
            entry(0, &uniform),
            entry(1, &self.texels),
            entry(2, &cols),
            entry(3, &rows),
            entry(4, &target),
        ];
        if let Some(luts) = &self.luts {
            entries.push(entry(5, luts));
        }
        let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("surftile fill"),
            layout: &self.pipeline.get_bind_group_layout(0),
            entries: &entries,
        });
        dispatch_fill(
            (device, queue),
            &self.pipeline,
            &bind,
            region,
            &target,
            out,
            (scope, "filling a region"),
        )
    }

    /// The toroidal rule's parameters and axes for `region` on levels `ls` (slot 1 read
    /// with weight `t`).
    fn toroidal_params(
        &self,
        s: &ToroidalSurface,
        region: &Region,
        ls: [usize; 2],
        t: f32,
    ) -> Result<(TorParams, Vec<TorAxis>, Vec<TorAxis>)> {
        let (w, h) = (region.width, region.height);
        let mut cols = vec![TorAxis::default(); 2 * w];
        let mut rows = vec![TorAxis::default(); 2 * h];
        let mut level = [TorLevel::default(); 2];
        let det = s.rhomboid.map_or(1, |r| r.det);
        // Quotient and remainder by det of a numerator change, as i32.
        let qr = |n: i128| -> Result<(i32, i32)> {
            let q = i32::try_from(n.div_euclid(det as i128)).map_err(|_| {
                Error::Limits("the region spans too many rhomboid cells for one GPU fill".into())
            })?;
            Ok((q, n.rem_euclid(det as i128) as i32))
        };
        let small = |v: i64| i32::try_from(v).map_err(|_| too_big("the lattice"));
        for (slot, &l) in ls.iter().enumerate() {
            let lv = &s.levels[l];
            let px = |col: usize| (region.x_at(col) - lv.centre) * lv.scale;
            let py = |row: usize| (region.y_at(row) - lv.centre) * lv.scale;
            let (xo, yo) = (floor_i(px(0)), floor_i(py(0)));
            // Rhomboid::cell takes a level-l texel at its level-0 position (x << l).
            let up = |v: i64| v.wrapping_shl(l as u32);
            let (ns0, nt0) = s.rhomboid.map_or((0, 0), |r| r.numerators(up(xo), up(yo)));
            let ((s0, rs0), (t0, rt0)) = (
                (ns0.div_euclid(det as i128), ns0.rem_euclid(det as i128)),
                (nt0.div_euclid(det as i128), nt0.rem_euclid(det as i128)),
            );
            let (u, v) = s.rhomboid.map_or(((0, 0), (0, 0)), |r| (r.u, r.v));
            for (k, a) in cols[slot * w..(slot + 1) * w].iter_mut().enumerate() {
                let p = px(k);
                (a.d, a.f) = rel(p, xo, "the region")?;
                let dx = up(a.d as i64) as i128;
                (a.sq, a.sr) = qr(v.1 as i128 * dx)?;
                (a.tq, a.tr) = qr(-(u.1 as i128) * dx)?;
            }
            for (k, a) in rows[slot * h..(slot + 1) * h].iter_mut().enumerate() {
                let p = py(k);
                (a.d, a.f) = rel(p, yo, "the region")?;
                let dy = up(a.d as i64) as i128;
                (a.sq, a.sr) = qr(-(v.0 as i128) * dy)?;
                (a.tq, a.tr) = qr(u.0 as i128 * dy)?;
            }
            let (i0, j0, lx0, ly0) = lv.locate(xo, yo);
            level[slot] = TorLevel {
                a: small(lv.a)?,
                b: small(lv.b)?,
                c: small(lv.c)?,
                tile_stride: u32::try_from(lv.tile_stride).map_err(|_| too_big("a tile"))?,
                texel_base: self.texel_base[l],
                lx0: lx0 as i32,
                ly0: ly0 as i32,
                rs0: rs0 as i32,
                i0: words(i0),
                j0: words(j0),
                s0: words(s0 as i64),
                t0: words(t0 as i64),
                ds_x: small(up(v.1))?,
                dt_x: small(up(-u.1))?,
                ds_y: small(up(-v.0))?,
                dt_y: small(up(u.0))?,
                rt0: rt0 as i32,
                pad: [0; 3],
            };
        }
        let params = TorParams {
            width: w as u32,
            height: h as u32,
            channels: self.channels as u32,
            tiles: s.tiles,
            seed: s.seed,
            det: if s.rhomboid.is_some() { small(det)? } else { 0 },
            t,
            colours: s.wang.unwrap_or(0),
            level,
        };
        Ok((params, cols, rows))
    }

    /// The blend rule's parameters and axes for `region` on levels `ls` (slot 1 read
    /// with weight `t`).
    fn blend_params(
        &self,
        s: &BlendSurface,
        region: &Region,
        ls: [usize; 2],
        t: f32,
    ) -> Result<(BlendParams, Vec<Axis>, Vec<Axis>)> {
        let (w, h) = (region.width, region.height);
        let (x0, y0) = (region.x_at(0), region.y_at(0));
        let (xo, yo) = (floor_i(x0), floor_i(y0));
        // The skewed grid s = (x·a − y·b, y·c) of BlendSurface::triangle, split into
        // its x and y terms.
        let bu_x = floor_i(x0 * s.skew_a);
        let bu_y = floor_i(-(y0 * s.skew_b));
        let bv_y = floor_i(y0 * s.skew_c);
        let mut cols = vec![Axis::default(); w];
        for (k, a) in cols.iter_mut().enumerate() {
            let x = region.x_at(k);
            (a.d, a.f) = rel(x, xo, "the region")?;
            (a.ui, a.uf) = rel(x * s.skew_a, bu_x, "the region")?;
        }
        let mut rows = vec![Axis::default(); h];
        for (k, a) in rows.iter_mut().enumerate() {
            let y = region.y_at(k);
            (a.d, a.f) = rel(y, yo, "the region")?;
            (a.ui, a.uf) = rel(-(y * s.skew_b), bu_y, "the region")?;
            (a.vi, a.vf) = rel(y * s.skew_c, bv_y, "the region")?;
        }
        let mut level = [BlendLevel::default(); 2];
        for (slot, &l) in ls.iter().enumerate() {
            let lv = &s.levels[l];
            level[slot] = BlendLevel {
                w: lv.w as u32,
                h: (lv.hmask + 1) as u32,
                tile_stride: u32::try_from(lv.tile_stride).map_err(|_| too_big("a tile"))?,
                texel_base: self.texel_base[l],
                lut_base: self.lut_base[l],
                pad0: 0,
                scale: lv.scale as f32,
                centre: lv.centre as f32,
                mean: lv.mean,
                lut_scale: lv.lut_scale,
            };
        }
        let params = BlendParams {
            width: w as u32,
            height: h as u32,
            channels: self.channels as u32,
            tiles: s.tiles,
            seed: s.seed,
            tile_shift: s.tile_shift,
            lut_size: s.lut_size as u32,
            pad0: 0,
            t,
            lut_last: s.lut_last,
            lut_centre: s.lut_centre,
            pad1: 0,
            mask_x: s.offset_mask_x as u32,
            mask_y: s.offset_mask_y as u32,
            xm0: (xo & s.offset_mask_x) as u32,
            ym0: (yo & s.offset_mask_y) as u32,
            bx0: words(bu_x.wrapping_add(bu_y)),
            by0: words(bv_y),
            level,
        };
        Ok((params, cols, rows))
    }
}

/// The blend rule's uniform `BlendParams` for a point sampler (`shaders/blend_sampler.wgsl`,
/// `export-shader`): level 0 in slot 0 at texel and table base 0, no second level, and
/// the region fields zero.
pub(crate) fn blend_sampler_params(s: &BlendSurface) -> Result<Vec<u8>> {
    let lv = &s.levels[0];
    let mut level = [BlendLevel::default(); 2];
    level[0] = BlendLevel {
        w: lv.w as u32,
        h: (lv.hmask + 1) as u32,
        tile_stride: u32::try_from(lv.tile_stride).map_err(|_| too_big("a tile"))?,
        texel_base: 0,
        lut_base: 0,
        pad0: 0,
        scale: lv.scale as f32,
        centre: lv.centre as f32,
        mean: lv.mean,
        lut_scale: lv.lut_scale,
    };
    let params = BlendParams {
        channels: s.channels as u32,
        tiles: s.tiles,
        seed: s.seed,
        tile_shift: s.tile_shift,
        lut_size: s.lut_size as u32,
        lut_last: s.lut_last,
        lut_centre: s.lut_centre,
        mask_x: s.offset_mask_x as u32,
        mask_y: s.offset_mask_y as u32,
        level,
        ..BlendParams::default()
    };
    Ok(bytemuck::bytes_of(&params).to_vec())
}

/// One input of [`gpu_hashes`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HashInput {
    /// Seed.
    pub seed: u32,
    /// Stream of `hash_cell`.
    pub stream: u32,
    /// Cell i.
    pub i: i64,
    /// Cell j.
    pub j: i64,
    /// Tile count for `pick_tile` (1..=65536).
    pub k: u32,
    /// A step for the 64-bit cell arithmetic: the GPU's `cell_add(i, d)`.
    pub d: i32,
}

/// What the GPU's hashes give for one [`HashInput`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HashOutput {
    /// `hash_cell(seed, i, j, stream)`.
    pub cell: [u32; 4],
    /// `hash_vertex(seed, i, j)`.
    pub vertex: [u32; 2],
    /// `hash_tile(seed, i, j)`.
    pub tile: u32,
    /// `pick_tile(hash_tile(seed, i, j), k)`.
    pub pick: u32,
    /// i + d, from the GPU's two-word cell arithmetic.
    pub sum: i64,
}

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct HashIn {
    seed: u32,
    stream: u32,
    i: [u32; 2],
    j: [u32; 2],
    k: u32,
    d: i32,
}

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct HashOut {
    cell: [u32; 4],
    vertex: [u32; 2],
    tile: u32,
    pick: u32,
    sum: [u32; 2],
    pad: [u32; 2],
}

/// Runs `shaders/hash.wgsl` on `inputs` (for the parity tests against [`crate::hash`]).
pub fn gpu_hashes(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    inputs: &[HashInput],
) -> Result<Vec<HashOutput>> {
    if inputs.is_empty() {
        return Ok(Vec::new());
    }
    let groups = u32::try_from(inputs.len().div_ceil(64))
        .ok()
        .filter(|&g| g <= u16::MAX as u32)
        .ok_or_else(|| Error::Limits(format!("{} hash inputs in one call", inputs.len())))?;
    let data: Vec<HashIn> = inputs
        .iter()
        .map(|v| HashIn {
            seed: v.seed,
            stream: v.stream,
            i: words(v.i),
            j: words(v.j),
            k: v.k,
            d: v.d,
        })
        .collect();
    let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
    let input = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("surftile hash inputs"),
        contents: bytemuck::cast_slice(&data),
        usage: wgpu::BufferUsages::STORAGE,
    });
    let bytes = (inputs.len() * std::mem::size_of::<HashOut>()) as u64;
    let target = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("surftile hash outputs"),
        size: bytes,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    let pipeline = pipeline(device, "hash_check", "check_hashes");
    let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("surftile hash check"),
        layout: &pipeline.get_bind_group_layout(0),
        entries: &[entry(0, &input), entry(1, &target)],
    });
    let result = dispatch_and_read(
        device,
        queue,
        &pipeline,
        &bind,
        [groups, 1],
        &target,
        bytes,
        bytemuck::pod_collect_to_vec::<u8, HashOut>,
    );
    check_scope(scope, "checking hashes")?;
    Ok(result?
        .iter()
        .map(|o| HashOutput {
            cell: o.cell,
            vertex: o.vertex,
            tile: o.tile,
            pick: o.pick,
            sum: (o.sum[0] as u64 | (o.sum[1] as u64) << 32) as i64,
        })
        .collect())
}

/// The refusal of a kind without a GPU twin.
fn unsupported(kind: &str, fill: GpuFill) -> Error {
    let why = match fill {
        GpuFill::Cpu(why) => why,
        _ => "no GPU twin",
    };
    Error::Unsupported(format!(
        "{kind} sources on the GPU ({why}; blend, toroidal and milling sources run there, this one fills on the CPU)"
    ))
}
