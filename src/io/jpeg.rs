//! JPEG reading (baseline and progressive; grey, YCbCr, CMYK), by `zune-jpeg`: a
//! photo as its 8-bit levels 0–255, as the PNG reader gives an 8-bit PNG. Grey stays
//! one channel; everything else decodes to RGB. JPEG holds no spacing or height unit.
//! Decoding is strict: a truncated or corrupt stream, or stray bytes between markers,
//! is refused rather than patched with grey.
//!
//! Before zune-jpeg sees a byte, [`check_structure`] walks the markers and refuses what
//! cameras and image editors do not write: odd sampling factors, a sequential image in
//! more than one scan, progressive scans out of order, precisions other than 8 bits,
//! DNL, arithmetic, lossless and hierarchical coding. zune-jpeg 0.5.15, the newest
//! release, still panics on some such files: its IDCT writes past a block row
//! (`fuzz/run jpeg` found one in CI; `tests/data/bad/jpeg-idct-past-row.jpg` is another).
//! Panics of the same kind are open upstream (zune-image issues 361, 362 and 409). A
//! photo a real encoder wrote passes the check unchanged.

use zune_jpeg::JpegDecoder;
use zune_jpeg::zune_core::bytestream::ZCursor;
use zune_jpeg::zune_core::colorspace::ColorSpace;
use zune_jpeg::zune_core::options::DecoderOptions;

use super::ImageFile;
use crate::error::{Error, Result};
use crate::raster::Raster;

pub(super) fn read(bytes: &[u8], what: &str) -> Result<ImageFile> {
    check_structure(bytes).map_err(|e| Error::decode(what, format!("not a valid JPEG ({e})")))?;
    let bad =
        |e: zune_jpeg::errors::DecodeErrors| Error::decode(what, format!("not a valid JPEG ({e})"));
    // JPEG sides are 16-bit; the pixel budget is check_shape's.
    let options = DecoderOptions::default()
        .set_max_width(usize::from(u16::MAX))
        .set_max_height(usize::from(u16::MAX))
        // Strict: a truncated or corrupt stream is an error. A lenient decode fills
        // what is missing with grey and goes on, and a half-grey photo would be baked
        // as if it were the texture.
        .set_strict_mode(true);
    // The headers first, for the size and the colour space, before anything is
    // decoded or allocated.
    let mut headers = JpegDecoder::new_with_options(ZCursor::new(bytes), options);
    headers.decode_headers().map_err(bad)?;
    let (w, h) = headers
        .dimensions()
        .ok_or_else(|| Error::decode(what, "not a valid JPEG (no frame header)"))?;
    let grey = matches!(
        headers.input_colorspace(),
        Some(ColorSpace::Luma | ColorSpace::LumaA)
    );
    let (space, channels) = if grey {
        (ColorSpace::Luma, 1)
    } else {
        (ColorSpace::RGB, 3)
    };
    super::check_shape(what, w, h, channels)?;
    // The output colour space is fixed when a decoder reads its headers: a second one.
    let mut decoder =
        JpegDecoder::new_with_options(ZCursor::new(bytes), options.jpeg_set_out_colorspace(space));
    decoder.decode_headers().map_err(bad)?;
    let size = decoder
        .output_buffer_size()
        .filter(|&n| n == w * h * channels)
        .ok_or_else(|| Error::decode(what, "not a valid JPEG (its frame size changed)"))?;
    let mut levels = vec![0u8; size];
    decoder.decode_into(&mut levels).map_err(bad)?;
    let data = levels.into_iter().map(f32::from).collect();
    Ok(ImageFile::new(
        Raster::from_vec(w, h, channels, data)?,
        None,
    ))
}

/// One frame component: id, sampling factors, quantisation table.
struct FrameComponent {
    id: u8,
    h: u8,
    v: u8,
    tq: u8,
}

/// Walks a JPEG's markers (ITU-T T.81, annex B) and refuses, with the reason, any
/// structure outside what real encoders write; see the module's notes. It reads
/// headers only and never decodes entropy-coded data, so it costs one pass over the
/// bytes. A file that ends inside its entropy-coded data passes here: the strict
/// decode refuses it after.
pub(super) fn check_structure(bytes: &[u8]) -> std::result::Result<(), String> {
    if !bytes.starts_with(&[0xff, 0xd8]) {
        return Err("no start-of-image marker".into());
    }
    let mut frame: Option<(u8, Vec<FrameComponent>)> = None;
    let mut quant = [false; 4];
    let mut huff = [[false; 4]; 2];
    let mut scans = 0usize;
    // Progressive: per component, per coefficient, the lowest bit decoded so far
    // (u8::MAX while none is).
    let mut decoded: Vec<[u8; 64]> = Vec::new();
    let mut at = 2;
    loop {
        // A marker: 0xFF, any fill bytes 0xFF, then its code.
        if bytes.get(at) != Some(&0xff) {
            if at >= bytes.len() {
                return Ok(());
            }
            return Err(format!("byte {at} is not a marker"));
        }
        while bytes.get(at) == Some(&0xff) {
            at += 1;
        }
        let Some(&code) = bytes.get(at) else {
            return Ok(());
        };
        at += 1;
        match code {
            0xd9 => {
                return if scans == 0 {
                    Err("it ends before any scan".into())
                } else {
                    Ok(())
                };
            }
            0xd0..=0xd7 => return Err(format!("a restart marker outside a scan at byte {at}")),
            0x00..=0xbf | 0xd8 | 0xf0..=0xfd => {
                return Err(format!(
                    "marker 0xFF{code:02X} at byte {} is not one of baseline or progressive JPEG's",
                    at - 2
                ));
            }
            _ => {}
        }
        let Some(&[hi, lo]) = bytes.get(at..at + 2) else {
            return Err(format!(
                "it ends inside marker 0xFF{code:02X}'s length at byte {at}"
            ));
        };
        let len = usize::from(u16::from_be_bytes([hi, lo]));
        if len < 2 || at + len > bytes.len() {
            return Err(format!(
                "marker 0xFF{code:02X} at byte {} has length {len}, and {} bytes follow it",
                at - 2,
                bytes.len() - at
            ));
        }
        let seg = &bytes[at + 2..at + len];
        at += len;
        match code {
            0xc0..=0xc2 => {
                if frame.is_some() {
                    return Err("a second frame header".into());
                }
                let comps = check_frame(seg)?;
                decoded = vec![[u8::MAX; 64]; comps.len()];
                frame = Some((code, comps));
            }
            0xc3 | 0xc5..=0xc7 | 0xc9..=0xcb | 0xcd..=0xcf => {
                return Err(format!(
                    "frame type 0xFF{code:02X} (lossless, hierarchical or arithmetic-coded) is not supported; expected baseline, extended or progressive Huffman"
                ));
            }
            0xc4 => check_huffman(seg, &mut huff)?,
            0xdb => check_quant(seg, &mut quant)?,
            0xdc => {
                return Err(
                    "a DNL marker (height defined after the first scan) is not supported".into(),
                );
            }
            0xdd if seg.len() != 2 => {
                return Err("a restart-interval segment that is not 4 bytes".into());
            }
            0xda => {
                let Some((kind, comps)) = &frame else {
                    return Err("a scan before the frame header".into());
                };
                scans += 1;
                check_scan(seg, *kind, comps, &quant, &huff, scans, &mut decoded)?;
                // Entropy-coded data runs to the next marker that is neither a
                // stuffed 0xFF00 nor a restart.
                loop {
                    match bytes.get(at..at + 2) {
                        None => return Ok(()),
                        Some([0xff, 0x00]) | Some([0xff, 0xd0..=0xd7]) => at += 2,
                        Some([0xff, 0xff]) => at += 1,
                        Some([0xff, _]) => break,
                        Some(_) => at += 1,
                    }
                }
            }
            // APPn, COM and a 4-byte DRI: nothing to check. (DHP and EXP belong to
            // hierarchical frames, refused at their frame header.)
            _ => {}
        }
    }
}

/// A frame header (SOF0–SOF2): 8-bit samples, 1, 3 or 4 components with distinct ids,
/// sampling factors 1 or 2 where every component samples either 1 × 1 or as the first
/// (4:4:4, 4:2:2, 4:2:0, 4:4:0; CMYK and YCCK alike), a single component 1 × 1.
fn check_frame(seg: &[u8]) -> std::result::Result<Vec<FrameComponent>, String> {
    let &[precision, h1, h0, w1, w0, n, ..] = seg else {
        return Err("a frame header shorter than 6 bytes".into());
    };
    if precision != 8 {
        return Err(format!("{precision}-bit samples; expected 8"));
    }
    let (height, width) = (u16::from_be_bytes([h1, h0]), u16::from_be_bytes([w1, w0]));
    if height == 0 || width == 0 {
        return Err(format!(
            "frame size {width} x {height}; expected both sides above 0"
        ));
    }
    if !matches!(n, 1 | 3 | 4) || seg.len() != 6 + 3 * usize::from(n) {
        return Err(format!(
            "a frame header of {} bytes for {n} components; expected 1, 3 or 4 components of 3 bytes each",
            seg.len()
        ));
    }
    let comps: Vec<FrameComponent> = seg[6..]
        .chunks_exact(3)
        .map(|c| FrameComponent {
            id: c[0],
            h: c[1] >> 4,
            v: c[1] & 15,
            tq: c[2],
        })
        .collect();
    let (h0, v0) = (comps[0].h, comps[0].v);
    for (i, c) in comps.iter().enumerate() {
        if comps[..i].iter().any(|d| d.id == c.id) {
            return Err(format!("component id {} twice in the frame", c.id));
        }
        if c.tq > 3 {
            return Err(format!(
                "component {} uses quantisation table {}; expected 0-3",
                c.id, c.tq
            ));
        }
        let factors = (1..=2).contains(&c.h) && (1..=2).contains(&c.v);
        let shape = i == 0 || (c.h, c.v) == (1, 1) || (c.h, c.v) == (h0, v0);
        let single = n > 1 || (c.h, c.v) == (1, 1);
        if !(factors && shape && single) {
            return Err(format!(
                "component {} samples {} x {} against the first's {h0} x {v0}; expected 1 x 1 or the first's, each 1 or 2",
                c.id, c.h, c.v
            ));
        }
    }
    Ok(comps)
}

/// Huffman tables: class 0 (DC) or 1 (AC), ids 0–3, at most 256 codes each.
fn check_huffman(mut seg: &[u8], defined: &mut [[bool; 4]; 2]) -> std::result::Result<(), String> {
    while let Some(&tc_th) = seg.first() {
        let (class, id) = (usize::from(tc_th >> 4), usize::from(tc_th & 15));
        if class > 1 || id > 3 {
            return Err(format!(
                "Huffman table class {class} id {id}; expected class 0 or 1, id 0-3"
            ));
        }
        let Some(counts) = seg.get(1..17) else {
            return Err("a Huffman table without its 16 code counts".into());
        };
        let total: usize = counts.iter().map(|&c| usize::from(c)).sum();
        if total > 256 || seg.len() < 17 + total {
            return Err(format!(
                "a Huffman table of {total} codes in a segment of {} bytes",
                seg.len()
            ));
        }
        defined[class][id] = true;
        seg = &seg[17 + total..];
    }
    Ok(())
}

/// Quantisation tables: 8- or 16-bit, ids 0–3.
fn check_quant(mut seg: &[u8], defined: &mut [bool; 4]) -> std::result::Result<(), String> {
    while let Some(&pq_tq) = seg.first() {
        let (precision, id) = (pq_tq >> 4, usize::from(pq_tq & 15));
        if precision > 1 || id > 3 {
            return Err(format!(
                "quantisation table precision {precision} id {id}; expected 0 or 1, id 0-3"
            ));
        }
        let size = 1 + 64 * (1 + usize::from(precision));
        if seg.len() < size {
            return Err("a quantisation table shorter than 64 entries".into());
        }
        defined[id] = true;
        seg = &seg[size..];
    }
    Ok(())
}

/// A scan header. Sequential frames: one scan of every component, all 64 coefficients.
/// Progressive frames (T.81, G.1.1.1): DC scans of one or more components, AC scans of
/// one, each band first decoded (Ah = 0) before it is refined one bit at a time
/// (Ah = Al + 1), and a component's DC before its AC.
fn check_scan(
    seg: &[u8],
    kind: u8,
    comps: &[FrameComponent],
    quant: &[bool; 4],
    huff: &[[bool; 4]; 2],
    scan: usize,
    decoded: &mut [[u8; 64]],
) -> std::result::Result<(), String> {
    let ns = usize::from(seg.first().copied().unwrap_or(0));
    if ns == 0 || ns > comps.len() || seg.len() != 4 + 2 * ns {
        return Err(format!(
            "a scan header of {} bytes for {ns} components",
            seg.len()
        ));
    }
    let (ss, se, ah, al) = (
        seg[1 + 2 * ns],
        seg[2 + 2 * ns],
        seg[3 + 2 * ns] >> 4,
        seg[3 + 2 * ns] & 15,
    );
    // A first DC scan decodes DC differences; every scan past coefficient 0 decodes AC.
    let (needs_dc, needs_ac) = (ss == 0 && ah == 0, se > 0);
    let mut members = Vec::with_capacity(ns);
    for pair in seg[1..1 + 2 * ns].chunks_exact(2) {
        let Some(k) = comps.iter().position(|c| c.id == pair[0]) else {
            return Err(format!(
                "a scan names component {}, which the frame lacks",
                pair[0]
            ));
        };
        if members.last().is_some_and(|&last| k <= last) {
            return Err("a scan's components are repeated or out of frame order".into());
        }
        let (td, ta) = (usize::from(pair[1] >> 4), usize::from(pair[1] & 15));
        if td > 3 || ta > 3 || (needs_dc && !huff[0][td]) || (needs_ac && !huff[1][ta]) {
            return Err(format!(
                "a scan uses Huffman tables DC {td} / AC {ta} before they are defined"
            ));
        }
        if !quant[usize::from(comps[k].tq)] {
            return Err(format!(
                "a scan comes before quantisation table {} is defined",
                comps[k].tq
            ));
        }
        members.push(k);
    }
    if kind != 0xc2 {
        if scan > 1 || ns != comps.len() || (ss, se, ah, al) != (0, 63, 0, 0) {
            return Err("a sequential image in more than one scan, or a scan of part of the spectrum; expected one scan of every component".into());
        }
        return Ok(());
    }
    let band_ok = if ss == 0 {
        se == 0
    } else {
        se >= ss && se <= 63 && ns == 1
    };
    let bits_ok = al <= 13 && (ah == 0 || ah == al + 1);
    if !band_ok || !bits_ok {
        return Err(format!(
            "a progressive scan of band {ss}-{se}, bits {ah}/{al}; expected DC alone or one component's AC band, refined one bit at a time"
        ));
    }
    // A first scan finds its band undecoded; a refinement finds it decoded down to Ah.
    let want = if ah == 0 { u8::MAX } else { ah };
    for &k in &members {
        let state = &mut decoded[k];
        if ss > 0 && state[0] == u8::MAX {
            return Err("a progressive AC scan before its component's DC scan".into());
        }
        for coefficient in &mut state[usize::from(ss)..=usize::from(se)] {
            if *coefficient != want {
                return Err(format!("progressive scan {scan} refines bits out of order"));
            }
            *coefficient = al;
        }
    }
    Ok(())
}
