//! The C ABI (feature `capi`): open a surface by spec and seed, sample and fill it from
//! C, C++ or anything with a C FFI. The header `include/surftile.h` is generated from
//! this file by cbindgen (`tests/capi.rs` fails when it is stale); `docs/capi.md` says how
//! to build, install and link the library.
//!
//! Rules every entry point keeps:
//! - it catches panics, so nothing unwinds into C ([`SurftileStatus::Panic`]);
//! - it checks its pointers and sizes before it touches them;
//! - on failure it returns a status and leaves a one-line message for
//!   [`surftile_last_error`] on the calling thread;
//! - a surface may be sampled and filled from several threads at once (it is
//!   immutable once opened); only [`surftile_free`] must not race with other calls on
//!   the same handle.
//!
//! Values are the Rust library's bit for bit: `surftile_fill` is
//! [`Surface::fill`](crate::Surface::fill) of
//! `Region::new(x, y, width, height).with_step(step)`.

use std::cell::RefCell;
use std::ffi::{CStr, CString, c_char};
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::PathBuf;

use crate::error::Error;
use crate::stream::{Region, Surface};

/// The version of this ABI: bumped whenever a signature, a status code or a struct
/// layout changes. Compare `surftile_abi_version` with it at run time.
pub const SURFTILE_ABI_VERSION: u32 = 1;

/// What every fallible entry point returns. The message behind a status other than
/// `SURFTILE_STATUS_OK` is `surftile_last_error()`.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SurftileStatus {
    /// Success.
    Ok = 0,
    /// A required pointer argument was null.
    NullPointer = 1,
    /// An argument is out of range: a zero size, a row stride shorter than a row, a
    /// non-finite origin, a step that is not positive, a spec that is not UTF-8.
    InvalidArgument = 2,
    /// The operating system refused a read (a missing file, say).
    Io = 3,
    /// A file could be read but is not a valid bank, configuration or image.
    BadFile = 4,
    /// A request exceeds a size limit.
    Limits = 5,
    /// A format feature or kind this build does not handle.
    Unsupported = 6,
    /// The library panicked: a bug in surftile; the message says where.
    Panic = 7,
}

/// An opened surface: what `surftile_open` hands out and `surftile_free` takes
/// back. Opaque to C.
pub struct SurftileSurface {
    surface: Box<dyn Surface>,
    spacing_um: f64,
}

thread_local! {
    static LAST_ERROR: RefCell<CString> = RefCell::new(CString::default());
}

/// Records `message` as this thread's last error (interior NULs become spaces, so
/// the whole message reaches C).
fn set_error(message: &str) {
    let bytes: Vec<u8> = message
        .bytes()
        .map(|b| if b == 0 { b' ' } else { b })
        .collect();
    let text = CString::new(bytes).unwrap_or_default();
    LAST_ERROR.with(|e| *e.borrow_mut() = text);
}

/// A status with its message, recorded for `surftile_last_error`.
fn fail(status: SurftileStatus, message: &str) -> SurftileStatus {
    set_error(message);
    status
}

/// The status a library error maps to.
fn status_of(e: &Error) -> SurftileStatus {
    match e {
        Error::Io { .. } => SurftileStatus::Io,
        Error::Decode { .. } | Error::BadBank { .. } => SurftileStatus::BadFile,
        Error::Limits(_) => SurftileStatus::Limits,
        Error::Unsupported(_) | Error::Gpu(_) => SurftileStatus::Unsupported,
        Error::InvalidParameter { .. }
        | Error::MissingData { .. }
        | Error::TooSmall { .. }
        | Error::Analysis { .. } => SurftileStatus::InvalidArgument,
    }
}

/// Runs `f`, turning a panic into [`SurftileStatus::Panic`] and an error into its
/// status, both with their message.
fn guard(what: &str, f: impl FnOnce() -> Result<(), SurftileStatus>) -> SurftileStatus {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(Ok(())) => SurftileStatus::Ok,
        Ok(Err(status)) => status,
        Err(payload) => fail(SurftileStatus::Panic, &panic_message(what, &*payload)),
    }
}

/// "surftile panicked in WHAT: MESSAGE", one line.
fn panic_message(what: &str, payload: &(dyn std::any::Any + Send)) -> String {
    let message = payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "a panic without a message".to_string());
    format!(
        "surftile panicked in {what} (a bug, please report it): {}",
        message.replace(['\n', '\r'], " ")
    )
}

/// A library error as its status, with its message recorded.
fn lib_error(e: Error) -> SurftileStatus {
    fail(status_of(&e), &e.to_string())
}

/// `ptr` as a reference, or the null-pointer status naming `name`.
///
/// # Safety
/// `ptr` is null or points to a live `T`.
unsafe fn non_null<'a, T>(ptr: *const T, what: &str, name: &str) -> Result<&'a T, SurftileStatus> {
    // SAFETY: the caller promises `ptr` is null or valid.
    unsafe { ptr.as_ref() }.ok_or_else(|| {
        fail(
            SurftileStatus::NullPointer,
            &format!("{what}: {name} is a null pointer; expected a valid pointer"),
        )
    })
}

/// The version of the ABI this library implements, `SURFTILE_ABI_VERSION`.
#[unsafe(no_mangle)]
pub extern "C" fn surftile_abi_version() -> u32 {
    SURFTILE_ABI_VERSION
}

/// The message of the last failed call on this thread, one line of UTF-8, or "" when
/// none failed yet. The pointer stays valid until the next failing call on this
/// thread; never null, never to be freed.
#[unsafe(no_mangle)]
pub extern "C" fn surftile_last_error() -> *const c_char {
    LAST_ERROR.with(|e| e.borrow().as_ptr())
}

/// Opens `spec` (a bank file, a milling or model `.toml`, or a preset name such as
/// "parallel-d4-ae05") placed with `seed`, and stores the new handle in `*out`.
/// On failure `*out` is set to null (when `out` itself is not null).
///
/// # Safety
/// `spec` is null or a NUL-terminated string; `out` is null or points to writable
/// storage for one pointer.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn surftile_open(
    spec: *const c_char,
    seed: u32,
    out: *mut *mut SurftileSurface,
) -> SurftileStatus {
    const WHAT: &str = "surftile_open";
    guard(WHAT, || {
        if out.is_null() {
            return Err(fail(
                SurftileStatus::NullPointer,
                "surftile_open: out is a null pointer; expected the address of a surftile_surface*",
            ));
        }
        // SAFETY: `out` is not null and the caller promises it is writable.
        unsafe { *out = std::ptr::null_mut() };
        // SAFETY: null or a NUL-terminated string, as the caller promises.
        let spec = unsafe { non_null(spec, WHAT, "spec") }?;
        // SAFETY: `spec` is a valid NUL-terminated string.
        let spec = unsafe { CStr::from_ptr(spec) };
        let path = spec_path(spec)?;
        let source = crate::open(&path).map_err(lib_error)?;
        let surface = source.surface(seed).map_err(lib_error)?;
        let handle = Box::new(SurftileSurface {
            surface,
            spacing_um: source.spacing_um().unwrap_or(f64::NAN),
        });
        // SAFETY: as above.
        unsafe { *out = Box::into_raw(handle) };
        Ok(())
    })
}

/// The spec as a path: its bytes on Unix, UTF-8 elsewhere.
fn spec_path(spec: &CStr) -> Result<PathBuf, SurftileStatus> {
    #[cfg(unix)]
    {
        use std::os::unix::ffi::OsStrExt;
        Ok(PathBuf::from(std::ffi::OsStr::from_bytes(spec.to_bytes())))
    }
    #[cfg(not(unix))]
    {
        spec.to_str().map(PathBuf::from).map_err(|_| {
            fail(
                SurftileStatus::InvalidArgument,
                "surftile_open: spec is not UTF-8; expected a UTF-8 path or preset name",
            )
        })
    }
}

/// Frees a handle from `surftile_open`. Null is accepted and ignored.
///
/// # Safety
/// `surface` is null or a handle from `surftile_open` not yet freed, and no other
/// call is using it.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn surftile_free(surface: *mut SurftileSurface) {
    if surface.is_null() {
        return;
    }
    // Dropping a surface does not panic; if it ever did, the handle would leak instead
    // of unwinding into C.
    let _ = catch_unwind(AssertUnwindSafe(|| {
        // SAFETY: a live handle from `surftile_open`, owned by the caller.
        drop(unsafe { Box::from_raw(surface) });
    }));
}

/// Values per sample: 1 for heights, 3 for RGB; 0 for a null handle.
///
/// # Safety
/// `surface` is null or a live handle.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn surftile_channels(surface: *const SurftileSurface) -> usize {
    // SAFETY: null or live, as the caller promises.
    match unsafe { surface.as_ref() } {
        Some(s) => catch_unwind(AssertUnwindSafe(|| s.surface.channels())).unwrap_or(0),
        None => {
            set_error("surftile_channels: surface is a null pointer; expected a valid pointer");
            0
        }
    }
}

/// Pixel spacing in µm; NaN where the source has none (a photo baked without one) or
/// for a null handle.
///
/// # Safety
/// `surface` is null or a live handle.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn surftile_spacing_um(surface: *const SurftileSurface) -> f64 {
    // SAFETY: null or live, as the caller promises.
    match unsafe { surface.as_ref() } {
        Some(s) => s.spacing_um,
        None => {
            set_error("surftile_spacing_um: surface is a null pointer; expected a valid pointer");
            f64::NAN
        }
    }
}

/// Channel 0 (the height) at (x, y), in surface pixels, at full resolution. NaN for a
/// null handle (with a message) and outside ±2^52 pixels or at NaN coordinates (the
/// surface's own contract).
///
/// # Safety
/// `surface` is null or a live handle.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn surftile_height(surface: *const SurftileSurface, x: f64, y: f64) -> f32 {
    const WHAT: &str = "surftile_height";
    let mut h = f32::NAN;
    guard(WHAT, || {
        // SAFETY: null or live, as the caller promises.
        let s = unsafe { non_null(surface, WHAT, "surface") }?;
        h = s.surface.height(x, y);
        Ok(())
    });
    h
}

/// Largest scratch buffer of a fill whose output rows are not contiguous: 16 MiB.
const STRIDED_BYTES: usize = 16 << 20;

/// Fills `width × height` samples starting at (x, y), `step` pixels apart, into `out`:
/// row r starts at `out + r·row_stride` (in floats) and holds `width × channels`
/// interleaved values. `row_stride` must be at least `width × channels`; `out` must hold
/// `(height − 1)·row_stride + width·channels` floats. Runs on all cores; the values do
/// not depend on their number. With `row_stride > width × channels` it allocates at most
/// 16 MiB of scratch.
///
/// # Safety
/// `surface` is null or a live handle; `out` is null or writable for the length above.
#[unsafe(no_mangle)]
#[allow(clippy::too_many_arguments)] // the signature the C API promises
pub unsafe extern "C" fn surftile_fill(
    surface: *const SurftileSurface,
    x: f64,
    y: f64,
    step: f64,
    width: usize,
    height: usize,
    out: *mut f32,
    row_stride: usize,
) -> SurftileStatus {
    const WHAT: &str = "surftile_fill";
    guard(WHAT, || {
        // SAFETY: null or live, as the caller promises.
        let s = unsafe { non_null(surface, WHAT, "surface") }?;
        if out.is_null() {
            return Err(fail(
                SurftileStatus::NullPointer,
                "surftile_fill: out is a null pointer; expected a float buffer",
            ));
        }
        let c = s.surface.channels();
        let region = Region::new(x, y, width, height).with_step(step);
        region
            .validate()
            .map_err(|e| fail(SurftileStatus::InvalidArgument, &format!("{WHAT}: {e}")))?;
        let row = width
            .checked_mul(c)
            .ok_or_else(|| too_big(width, height, c))?;
        if row_stride < row {
            return Err(fail(
                SurftileStatus::InvalidArgument,
                &format!(
                    "surftile_fill: row_stride = {row_stride}: expected at least width × channels = {width} × {c} = {row} floats"
                ),
            ));
        }
        let len = (height - 1)
            .checked_mul(row_stride)
            .and_then(|n| n.checked_add(row))
            .filter(|&n| n <= isize::MAX as usize / size_of::<f32>())
            .ok_or_else(|| too_big(width, height, c))?;
        // SAFETY: the caller promises `out` is writable for `len` floats; `len` fits in
        // an isize worth of bytes (checked above).
        let out = unsafe { std::slice::from_raw_parts_mut(out, len) };
        if row_stride == row {
            return s.surface.fill(&region, out).map_err(lib_error);
        }
        // Rows are not contiguous: fill bands of rows into a scratch buffer of at most
        // STRIDED_BYTES and copy them out; a row longer than that is filled in place.
        let band_rows = (STRIDED_BYTES / (row * size_of::<f32>())).clamp(1, height);
        if band_rows == 1 {
            for r in 0..height {
                let sub = region.sub(0, r, width, 1).map_err(lib_error)?;
                let start = r * row_stride;
                s.surface
                    .fill(&sub, &mut out[start..start + row])
                    .map_err(lib_error)?;
            }
            return Ok(());
        }
        let mut band = vec![0.0f32; band_rows * row];
        for r0 in (0..height).step_by(band_rows) {
            let rows = band_rows.min(height - r0);
            let sub = region.sub(0, r0, width, rows).map_err(lib_error)?;
            let band = &mut band[..rows * row];
            s.surface.fill(&sub, band).map_err(lib_error)?;
            for (i, src) in band.chunks_exact(row).enumerate() {
                let start = (r0 + i) * row_stride;
                out[start..start + row].copy_from_slice(src);
            }
        }
        Ok(())
    })
}

/// The status for a region whose buffer length overflows.
fn too_big(width: usize, height: usize, c: usize) -> SurftileStatus {
    fail(
        SurftileStatus::Limits,
        &format!(
            "surftile_fill: {width}×{height}×{c} floats: expected a buffer that fits in the address space"
        ),
    )
}
