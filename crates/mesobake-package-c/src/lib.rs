//! The C ABI of `mesobake-package`, for engines and build tools written in C or C++: open a
//! package (validated exactly as mesobake validates it), read its manifest, reach each
//! section's bytes with the texture they upload to, and query its GDM and its radiance
//! transfer (the RTV at the baked samples, the PRT per base-mesh vertex). The header
//! `include/mesobake_package.h` is generated from this file by cbindgen.
//!
//! Conventions: every function accepts a null package pointer and then returns its failure
//! value; strings are NUL-terminated UTF-8 owned by the package, valid until
//! [`mbpkg_close`]; nothing here panics across the boundary.

use mesobake_package::gi::{RadianceTransfer, SH_COEFFS};
use mesobake_package::manifest::{GdmCodec, TexelFormat, TextureDimension};
use mesobake_package::{GdmQuery, Package};
use std::ffi::{CStr, CString, c_char};
use std::path::Path;

/// An open package (opaque).
pub struct MbpkgPackage {
    package: Package,
    query: GdmQuery,
    transfer: Option<RadianceTransfer>,
    manifest_json: CString,
    section_names: Vec<CString>,
}

/// How the package answers GDM queries.
#[repr(u32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MbpkgCodec {
    /// The voxel occupancy with empty-space distances, marched exactly.
    Occupancy = 0,
    /// The paper's truncated SVD: weight maps times eigenmaps.
    PaperSvd = 1,
}

/// What a section uploads to.
#[repr(u32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MbpkgDimension {
    /// A 2D texture.
    D2 = 0,
    /// A 3D texture.
    D3 = 1,
    /// A storage buffer of `width` texels.
    Buffer = 2,
}

/// Texel formats, named as in WebGPU (little-endian; unorm codes read as code / 255).
#[repr(u32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MbpkgFormat {
    /// One f32.
    R32float = 0,
    /// Two f32.
    Rg32float = 1,
    /// Four f32.
    Rgba32float = 2,
    /// One binary16.
    R16float = 3,
    /// Two binary16.
    Rg16float = 4,
    /// Four binary16.
    Rgba16float = 5,
    /// One 8-bit unorm code.
    R8unorm = 6,
    /// Two 8-bit unorm codes.
    Rg8unorm = 7,
    /// Four 8-bit unorm codes.
    Rgba8unorm = 8,
    /// One 8-bit unsigned integer.
    R8uint = 9,
    /// One 32-bit unsigned integer.
    R32uint = 10,
}

/// The voxel grid and the direction grid of a package.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MbpkgGrid {
    /// Voxels along x, y, z.
    pub res: [u32; 3],
    /// Direction bins along θ and φ (θ_a = (a + ½)·π/Nθ, φ_b = (b + ½)·2π/Nφ).
    pub dirs: [u32; 2],
}

/// One binary section: its name, its texels (inflated where the package stores them
/// supercompressed) and the texture they fill (tightly packed, x fastest).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct MbpkgSection {
    /// The section's name.
    pub name: *const c_char,
    /// Its texels' bytes.
    pub data: *const u8,
    /// Their count.
    pub len: usize,
    /// Texture dimensionality.
    pub dimension: MbpkgDimension,
    /// Texel format.
    pub format: MbpkgFormat,
    /// Texels per row.
    pub width: u32,
    /// Rows per image.
    pub height: u32,
    /// Images.
    pub depth: u32,
}

/// Writes `message` into the caller's buffer, truncated and NUL-terminated.
///
/// # Safety
/// `error` is null or points to `error_len` writable bytes.
unsafe fn write_error(message: &str, error: *mut c_char, error_len: usize) {
    if error.is_null() || error_len == 0 {
        return;
    }
    let bytes = message.as_bytes();
    let n = bytes.len().min(error_len - 1);
    // SAFETY: the caller provides error_len writable bytes; n + 1 ≤ error_len.
    unsafe {
        std::ptr::copy_nonoverlapping(bytes.as_ptr(), error.cast::<u8>(), n);
        *error.add(n) = 0;
    }
}

impl MbpkgPackage {
    /// Whether voxel (i, j, k) and direction bin (a, b) lie on the package's grids.
    fn on_grids(&self, [i, j, k]: [u32; 3], [a, b]: [u32; 2]) -> bool {
        let (d, g) = (self.package.dims(), self.package.dirs());
        i < d.x && j < d.y && k < d.z && a < g.n_theta && b < g.n_phi
    }
}

fn open(package: mesobake_package::Result<Package>) -> Result<Box<MbpkgPackage>, String> {
    let package = package.map_err(|e| e.to_string())?;
    let query = package.query().map_err(|e| e.to_string())?;
    let transfer = (package.radiance_transfer().transpose()).map_err(|e| e.to_string())?;
    let json = serde_json::to_string(package.manifest()).map_err(|e| e.to_string())?;
    let cstring = |s: &str| CString::new(s).map_err(|_| "a name holds a NUL byte".to_string());
    let section_names = (package.manifest().sections.iter())
        .map(|s| cstring(&s.name))
        .collect::<Result<_, _>>()?;
    Ok(Box::new(MbpkgPackage {
        manifest_json: cstring(&json)?,
        package,
        query,
        transfer,
        section_names,
    }))
}

fn finish(
    result: Result<Box<MbpkgPackage>, String>,
    error: *mut c_char,
    error_len: usize,
) -> *mut MbpkgPackage {
    match result {
        Ok(package) => Box::into_raw(package),
        Err(message) => {
            // SAFETY: forwarded from the caller's contract.
            unsafe { write_error(&message, error, error_len) };
            std::ptr::null_mut()
        }
    }
}

/// Opens and validates the package at `path`, refusing before allocating a file over
/// `max_bytes` or a package whose reading (the file, its sections inflated and decoded) would
/// take more memory than that. Returns null on failure, with the reason in `error` (truncated
/// to `error_len` bytes, NUL-terminated).
///
/// # Safety
/// `path` is a NUL-terminated string; `error` is null or has `error_len` writable bytes.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn mbpkg_open(
    path: *const c_char,
    max_bytes: u64,
    error: *mut c_char,
    error_len: usize,
) -> *mut MbpkgPackage {
    if path.is_null() {
        return finish(Err("the path is null".into()), error, error_len);
    }
    // SAFETY: the caller passes a NUL-terminated string.
    let path = unsafe { CStr::from_ptr(path) };
    let result = match path.to_str() {
        Ok(p) => open(Package::read(Path::new(p), max_bytes)),
        Err(_) => Err("the path is not UTF-8".into()),
    };
    finish(result, error, error_len)
}

/// Validates the `len` bytes at `bytes` as a package (copying them), within `max_bytes` of
/// memory as for [`mbpkg_open`]. Returns null on failure, with the reason in `error`.
///
/// # Safety
/// `bytes` points to `len` readable bytes; `error` is null or has `error_len` writable bytes.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn mbpkg_parse(
    bytes: *const u8,
    len: usize,
    max_bytes: u64,
    error: *mut c_char,
    error_len: usize,
) -> *mut MbpkgPackage {
    if bytes.is_null() {
        return finish(Err("the bytes are null".into()), error, error_len);
    }
    if len as u64 > max_bytes {
        let message = format!("the package's {len} bytes are over the limit of {max_bytes}");
        return finish(Err(message), error, error_len);
    }
    // SAFETY: the caller passes len readable bytes.
    let bytes = unsafe { std::slice::from_raw_parts(bytes, len) }.to_vec();
    finish(
        open(Package::parse_within(bytes, max_bytes)),
        error,
        error_len,
    )
}

/// Closes a package opened by [`mbpkg_open`] or [`mbpkg_parse`] (null is ignored).
///
/// # Safety
/// `package` is null or came from this library and is not used afterwards.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn mbpkg_close(package: *mut MbpkgPackage) {
    if !package.is_null() {
        // SAFETY: the pointer came from Box::into_raw in this library.
        drop(unsafe { Box::from_raw(package) });
    }
}

/// The manifest as JSON (see docs/package-format.md); null for a null package.
///
/// # Safety
/// `package` is null or open.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn mbpkg_manifest_json(package: *const MbpkgPackage) -> *const c_char {
    // SAFETY: null or open, by the caller's contract.
    unsafe { package.as_ref() }.map_or(std::ptr::null(), |p| p.manifest_json.as_ptr())
}

/// The package's grids (all zero for a null package).
///
/// # Safety
/// `package` is null or open.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn mbpkg_grid(package: *const MbpkgPackage) -> MbpkgGrid {
    // SAFETY: null or open, by the caller's contract.
    unsafe { package.as_ref() }.map_or(MbpkgGrid::default(), |p| {
        let (d, g) = (p.package.dims(), p.package.dirs());
        MbpkgGrid {
            res: [d.x, d.y, d.z],
            dirs: [g.n_theta, g.n_phi],
        }
    })
}

/// The package's codec (occupancy for a null package).
///
/// # Safety
/// `package` is null or open.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn mbpkg_codec(package: *const MbpkgPackage) -> MbpkgCodec {
    // SAFETY: null or open, by the caller's contract.
    match unsafe { package.as_ref() }.map(|p| p.package.manifest().codec) {
        Some(GdmCodec::PaperSvd) => MbpkgCodec::PaperSvd,
        _ => MbpkgCodec::Occupancy,
    }
}

/// The number of sections (0 for a null package).
///
/// # Safety
/// `package` is null or open.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn mbpkg_section_count(package: *const MbpkgPackage) -> usize {
    // SAFETY: null or open, by the caller's contract.
    unsafe { package.as_ref() }.map_or(0, |p| p.section_names.len())
}

/// Fills `out` with section `index` (in file order). Returns false when the package is null
/// or `index` is out of range.
///
/// # Safety
/// `package` is null or open; `out` is null or writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn mbpkg_section(
    package: *const MbpkgPackage,
    index: usize,
    out: *mut MbpkgSection,
) -> bool {
    // SAFETY: null or open / writable, by the caller's contract.
    let (Some(p), Some(out)) = (unsafe { package.as_ref() }, unsafe { out.as_mut() }) else {
        return false;
    };
    let Some(section) = p.package.manifest().sections.get(index) else {
        return false;
    };
    let bytes = p.package.section(&section.name).expect("listed");
    let t = section.texture;
    *out = MbpkgSection {
        name: p.section_names[index].as_ptr(),
        data: bytes.as_ptr(),
        len: bytes.len(),
        dimension: match t.dimension {
            TextureDimension::D2 => MbpkgDimension::D2,
            TextureDimension::D3 => MbpkgDimension::D3,
            TextureDimension::Buffer => MbpkgDimension::Buffer,
        },
        format: format(t.format),
        width: t.width,
        height: t.height,
        depth: t.depth,
    };
    true
}

fn format(f: TexelFormat) -> MbpkgFormat {
    use MbpkgFormat as M;
    match f {
        TexelFormat::R32float => M::R32float,
        TexelFormat::Rg32float => M::Rg32float,
        TexelFormat::Rgba32float => M::Rgba32float,
        TexelFormat::R16float => M::R16float,
        TexelFormat::Rg16float => M::Rg16float,
        TexelFormat::Rgba16float => M::Rgba16float,
        TexelFormat::R8unorm => M::R8unorm,
        TexelFormat::Rg8unorm => M::Rg8unorm,
        TexelFormat::Rgba8unorm => M::Rgba8unorm,
        TexelFormat::R8uint => M::R8uint,
        TexelFormat::R32uint => M::R32uint,
    }
}

/// The GDM at voxel centre (i, j, k) along direction bin (a, b): returns 1 and writes the
/// distance (voxels) to `distance` for a hit, 0 for an escape, −1 when the package is null or
/// a coordinate is off the grids.
///
/// # Safety
/// `package` is null or open; `distance` is null or writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn mbpkg_distance(
    package: *const MbpkgPackage,
    i: u32,
    j: u32,
    k: u32,
    a: u32,
    b: u32,
    distance: *mut f32,
) -> i32 {
    // SAFETY: null or open, by the caller's contract.
    let Some(p) = (unsafe { package.as_ref() }).filter(|p| p.on_grids([i, j, k], [a, b])) else {
        return -1;
    };
    match p.query.distance(i, j, k, a, b) {
        Some(value) => {
            // SAFETY: null or writable, by the caller's contract.
            if let Some(out) = unsafe { distance.as_mut() } {
                *out = value;
            }
            1
        }
        None => 0,
    }
}

/// The RTV's transfer vector at voxel centre (i, j, k) towards the centre of view bin (a, b):
/// writes 48 floats to `out`, per colour channel c the weights t of the 16 SH coefficients l
/// of the light arriving in the vertex's local frame at `out[16·c + l]` (the radiance towards
/// the view is L_c = Σ_l t[16·c + l]·ℓ_local,c,l; see the package format). Returns 1 for an
/// RTV sample voxel, 0 for a voxel that is not one (nothing written), −1 when the package is
/// null, holds no radiance transfer, or a coordinate is off the grids.
///
/// # Safety
/// `package` is null or open; `out` is null or has 48 writable floats.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn mbpkg_rtv_transfer(
    package: *const MbpkgPackage,
    i: u32,
    j: u32,
    k: u32,
    a: u32,
    b: u32,
    out: *mut f32,
) -> i32 {
    // SAFETY: null or open, by the caller's contract.
    let Some(p) = (unsafe { package.as_ref() }).filter(|p| p.on_grids([i, j, k], [a, b])) else {
        return -1;
    };
    let Some(transfer) = &p.transfer else {
        return -1;
    };
    match transfer.transfer_at_bin([i, j, k], [a, b]) {
        Some(vector) => {
            if !out.is_null() {
                // SAFETY: out has 48 writable floats, by the caller's contract.
                let out = unsafe { std::slice::from_raw_parts_mut(out, 3 * SH_COEFFS) };
                out.copy_from_slice(vector.as_flattened());
            }
            1
        }
        None => 0,
    }
}

/// The PRT matrix T of base-mesh vertex `vertex` (16×16, row-major), copied to `out`: it takes
/// the environment's SH (world frame) to the light arriving at the vertex in its local frame,
/// ℓ_local,i = Σⱼ T[i][j]·ℓ_world,j. Returns false when the
/// package is null, holds no radiance transfer, or `vertex` is past the last.
///
/// # Safety
/// `package` is null or open; `out` is null or has 256 writable floats.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn mbpkg_prt_matrix(
    package: *const MbpkgPackage,
    vertex: u32,
    out: *mut f32,
) -> bool {
    // SAFETY: null or open, by the caller's contract.
    let Some(p) = (unsafe { package.as_ref() }) else {
        return false;
    };
    let Some(matrix) = (p.transfer.as_ref()).and_then(|t| t.prt_matrix(vertex as usize)) else {
        return false;
    };
    if !out.is_null() {
        // SAFETY: out has 256 writable floats, by the caller's contract.
        unsafe { std::ptr::copy_nonoverlapping(matrix.as_ptr(), out, matrix.len()) };
    }
    true
}
