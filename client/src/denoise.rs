//! Denoising with Intel Open Image Denoise (OIDN 2.x), loaded at run time so that building
//! and running Tessera never needs it: `--denoise` finds `libOpenImageDenoise` through
//! `TESSERA_OIDN_LIB`, else in PyPI's `pyoidn` wheel, else on the loader path, and says how
//! to install it when none is there.
//!
//! The `RT` filter runs on the HDR beauty with the albedo and normal AOVs as auxiliary
//! images, each first filtered alone so their own noise does not reach the result (OIDN's
//! documentation: "prefiltering" the auxiliary images, then `cleanAux`).

use std::ffi::{CStr, CString, c_char, c_void};
use std::path::PathBuf;

use anyhow::{Context, Result, bail};

use crate::output::Image;

/// How to get the library, said whenever it is missing.
pub const INSTALL_HINT: &str = "denoising needs Intel Open Image Denoise 2.x: `python3 -m pip install pyoidn==2.5.1.0` \
(or set TESSERA_OIDN_LIB to a libOpenImageDenoise.so)";

const OIDN_DEVICE_TYPE_CPU: i32 = 1;
const OIDN_FORMAT_FLOAT3: i32 = 3;

type NewDevice = unsafe extern "C" fn(i32) -> *mut c_void;
type DeviceFn = unsafe extern "C" fn(*mut c_void);
type SetDeviceInt = unsafe extern "C" fn(*mut c_void, *const c_char, i32);
type GetDeviceError = unsafe extern "C" fn(*mut c_void, *mut *const c_char) -> i32;
type NewFilter = unsafe extern "C" fn(*mut c_void, *const c_char) -> *mut c_void;
type SetImage = unsafe extern "C" fn(*mut c_void, *const c_char, *mut c_void, i32, usize, usize, usize, usize, usize);
type SetBool = unsafe extern "C" fn(*mut c_void, *const c_char, bool);
type FilterFn = unsafe extern "C" fn(*mut c_void);

/// Where the OIDN library is, without loading it.
pub fn library_path() -> Result<PathBuf> {
    if let Some(p) = std::env::var_os("TESSERA_OIDN_LIB") {
        return Ok(PathBuf::from(p));
    }
    // PyPI's pyoidn wheel ships the library and its CPU device.
    let found = std::process::Command::new("python3")
        .args(["-c", "import os, pyoidn; print(os.path.join(os.path.dirname(pyoidn.__file__), 'oidn', 'lib', 'libOpenImageDenoise.so.2'))"])
        .output()
        .ok()
        .filter(|o| o.status.success())
        .map(|o| PathBuf::from(String::from_utf8_lossy(&o.stdout).trim()));
    Ok(found.filter(|p| p.exists()).unwrap_or_else(|| PathBuf::from("libOpenImageDenoise.so.2")))
}

/// An OIDN CPU device.
pub struct Denoiser {
    lib: libloading::Library,
    device: *mut c_void,
}

// SAFETY: an OIDN device may be used from any thread, one call at a time; `&mut self` and
// the owning thread keep calls apart.
unsafe impl Send for Denoiser {}

impl Denoiser {
    /// Loads the library and creates a CPU device on `threads` threads (0: all).
    pub fn new(threads: usize) -> Result<Denoiser> {
        let path = library_path()?;
        // SAFETY: loading OIDN runs its initialisers, which have no preconditions.
        let lib = unsafe { libloading::Library::new(&path) }.map_err(|e| anyhow::anyhow!("{INSTALL_HINT} ({}: {e})", path.display()))?;
        let mut d = Denoiser { lib, device: std::ptr::null_mut() };
        // SAFETY: the symbols have the C signatures of OIDN 2.x's public API (oidn.h).
        unsafe {
            d.device = d.sym::<NewDevice>(b"oidnNewDevice\0")?(OIDN_DEVICE_TYPE_CPU);
            if threads > 0 {
                d.sym::<SetDeviceInt>(b"oidnSetDeviceInt\0")?(d.device, c"numThreads".as_ptr(), threads as i32);
            }
            d.sym::<DeviceFn>(b"oidnCommitDevice\0")?(d.device);
        }
        d.check()?;
        Ok(d)
    }

    fn sym<T: Copy>(&self, name: &[u8]) -> Result<T> {
        // SAFETY: callers name a symbol with the type T it has.
        unsafe { self.lib.get::<T>(name).map(|s| *s).with_context(|| format!("{INSTALL_HINT}: missing {}", String::from_utf8_lossy(name))) }
    }

    fn check(&self) -> Result<()> {
        let mut message: *const c_char = std::ptr::null();
        // SAFETY: the device is live; OIDN writes a static or device-owned string.
        let code = unsafe { self.sym::<GetDeviceError>(b"oidnGetDeviceError\0")?(self.device, &mut message) };
        if code != 0 {
            let text = if message.is_null() { "unknown".into() } else { unsafe { CStr::from_ptr(message) }.to_string_lossy() };
            bail!("Open Image Denoise failed (error {code}): {text}");
        }
        Ok(())
    }

    /// Runs one `RT` filter over `images` (name, pixels, channels per pixel: the first three
    /// are read or written) with `flags` set, writing `output` (3 floats per pixel).
    fn run(&self, (w, h): (usize, usize), images: &mut [(&str, &mut [f32], usize)], flags: &[(&str, bool)]) -> Result<()> {
        // SAFETY: every image holds w·h pixels of `channels` floats and outlives the filter.
        unsafe {
            let filter = self.sym::<NewFilter>(b"oidnNewFilter\0")?(self.device, c"RT".as_ptr());
            for (name, pixels, channels) in images.iter_mut() {
                assert_eq!(pixels.len(), w * h * *channels, "{name}: wrong size");
                let name = CString::new(*name).expect("no NUL");
                let stride = 4 * *channels;
                self.sym::<SetImage>(b"oidnSetSharedFilterImage\0")?(
                    filter,
                    name.as_ptr(),
                    pixels.as_mut_ptr().cast(),
                    OIDN_FORMAT_FLOAT3,
                    w,
                    h,
                    0,
                    stride,
                    stride * w,
                );
            }
            for (name, value) in flags {
                let name = CString::new(*name).expect("no NUL");
                self.sym::<SetBool>(b"oidnSetFilterBool\0")?(filter, name.as_ptr(), *value);
            }
            self.sym::<FilterFn>(b"oidnCommitFilter\0")?(filter);
            self.sym::<FilterFn>(b"oidnExecuteFilter\0")?(filter);
            self.sym::<FilterFn>(b"oidnReleaseFilter\0")?(filter);
        }
        self.check()
    }

    /// The denoised RGB of `color` (`channels` floats per pixel, RGB first), with the
    /// prefiltered `albedo` and `normal` (3 floats per pixel) as guides. Non-finite inputs
    /// are read as 0; the result is finite and not clamped.
    pub fn denoise(&self, (w, h): (usize, usize), color: &[f32], channels: usize, albedo: &[f32], normal: &[f32]) -> Result<Vec<f32>> {
        let finite = |v: &[f32]| v.iter().map(|x| if x.is_finite() { *x } else { 0.0 }).collect::<Vec<f32>>();
        let (mut color, mut albedo, mut normal) = (finite(color), finite(albedo), finite(normal));
        if color.chunks(channels).all(|p| p[..3] == [0.0; 3]) {
            // Nothing to denoise; the network would answer with its own floor (~5e-4).
            return Ok(vec![0.0; w * h * 3]);
        }
        let (mut albedo_clean, mut normal_clean) = (vec![0.0; w * h * 3], vec![0.0; w * h * 3]);
        self.run((w, h), &mut [("albedo", &mut albedo, 3), ("output", &mut albedo_clean, 3)], &[])?;
        self.run((w, h), &mut [("normal", &mut normal, 3), ("output", &mut normal_clean, 3)], &[])?;
        let mut out = vec![0.0; w * h * 3];
        self.run(
            (w, h),
            &mut [
                ("color", &mut color, channels),
                ("albedo", &mut albedo_clean, 3),
                ("normal", &mut normal_clean, 3),
                ("output", &mut out, 3),
            ],
            &[("hdr", true), ("cleanAux", true)],
        )?;
        // HDR in, linear out, nothing clamped; only a non-finite value (never seen) is zeroed.
        Ok(out.into_iter().map(|x| if x.is_finite() { x } else { 0.0 }).collect())
    }
}

impl Drop for Denoiser {
    fn drop(&mut self) {
        if !self.device.is_null()
            && let Ok(release) = self.sym::<DeviceFn>(b"oidnReleaseDevice\0")
        {
            // SAFETY: the device is live and released once.
            unsafe { release(self.device) };
        }
    }
}

/// The layers `--denoise` adds: `beauty_denoised` (denoised RGB, the raw alpha) and
/// `<aov>_denoised` for each light-path AOV present, guided by the image's albedo and
/// normal. Returns the names added.
pub fn denoise_image(image: &mut Image, denoiser: &Denoiser) -> Result<Vec<String>> {
    let (Some((3, albedo)), Some((3, normal))) = (image.layers.get("albedo"), image.layers.get("normal")) else {
        bail!("denoising needs the albedo and normal AOVs");
    };
    let (albedo, normal) = (albedo.clone(), normal.clone());
    let size = (image.width as usize, image.height as usize);
    let targets: Vec<String> = image
        .layers
        .keys()
        .filter(|k| {
            *k == "beauty" || render_core::film::Aov::from_name(k).is_some_and(|a| a.is_extra() && a != render_core::film::Aov::Position)
        })
        .cloned()
        .collect();
    let mut added = Vec::new();
    for name in targets {
        let (channels, pixels) = image.layers[&name].clone();
        let rgb = denoiser.denoise(size, &pixels, channels as usize, &albedo, &normal)?;
        let mut out = pixels.clone();
        for (px, d) in out.chunks_mut(channels as usize).zip(rgb.chunks(3)) {
            px[..3].copy_from_slice(d);
        }
        let layer = format!("{name}_denoised");
        image.layers.insert(layer.clone(), (channels, out));
        added.push(layer);
    }
    Ok(added)
}
