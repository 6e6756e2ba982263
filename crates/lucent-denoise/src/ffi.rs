//! The only `unsafe` code in Lucent: Intel Open Image Denoise's C API,
//! loaded with `libloading` and called through function pointers.
//!
//! Every call here is checked against OIDN 2's `oidn.h` (OIDN 2.0 to 2.x
//! keep this ABI): handles are opaque pointers, enums are C `int`s, sizes
//! `size_t`. The safety argument of each block is beside it; in short:
//! - the library stays loaded as long as any function pointer taken from
//!   it ([`Api`] owns the `Library` beside the pointers);
//! - a device or filter handle is used only while its owner is alive, and
//!   released exactly once (`Drop`);
//! - the images handed to OIDN are borrowed slices whose length was checked
//!   against `width * height * 3` before the call, and they outlive the
//!   synchronous `oidnExecuteFilter` that reads and writes them.
#![allow(unsafe_code, reason = "the one FFI module, recorded in ARCHITECTURE.md")]

use std::ffi::{CStr, CString, c_char, c_int, c_void};
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};

type Device = *mut c_void;
type Filter = *mut c_void;

/// `OIDN_DEVICE_TYPE_CPU`.
const DEVICE_TYPE_CPU: c_int = 1;
/// `OIDN_FORMAT_FLOAT3`.
const FORMAT_FLOAT3: c_int = 3;
/// `OIDN_ERROR_NONE`.
const ERROR_NONE: c_int = 0;
/// `OIDN_ERROR_CANCELLED` (OIDN 2's numbering).
const ERROR_CANCELLED: c_int = 6;

/// `OIDNProgressMonitorFunction`: called with the user pointer and the
/// progress in [0, 1]; returning false cancels the filter.
type ProgressMonitor = unsafe extern "C" fn(*mut c_void, f64) -> bool;

/// Why a filter run gave no image.
#[derive(Debug)]
pub(crate) enum RunError {
    /// The cancel flag was set while it ran.
    Cancelled,
    /// OIDN reported an error, or the images did not fit.
    Failed(String),
}

impl From<String> for RunError {
    fn from(e: String) -> Self {
        RunError::Failed(e)
    }
}

/// The entry points used, resolved once.
pub(crate) struct Api {
    new_device: unsafe extern "C" fn(c_int) -> Device,
    set_device_int: unsafe extern "C" fn(Device, *const c_char, c_int),
    commit_device: unsafe extern "C" fn(Device),
    get_device_error: unsafe extern "C" fn(Device, *mut *const c_char) -> c_int,
    release_device: unsafe extern "C" fn(Device),
    new_filter: unsafe extern "C" fn(Device, *const c_char) -> Filter,
    set_shared_filter_image:
        unsafe extern "C" fn(Filter, *const c_char, *mut c_void, c_int, usize, usize, usize, usize, usize),
    set_filter_bool: unsafe extern "C" fn(Filter, *const c_char, bool),
    set_filter_int: unsafe extern "C" fn(Filter, *const c_char, c_int),
    set_filter_progress_monitor: unsafe extern "C" fn(Filter, Option<ProgressMonitor>, *mut c_void),
    commit_filter: unsafe extern "C" fn(Filter),
    execute_filter: unsafe extern "C" fn(Filter),
    release_filter: unsafe extern "C" fn(Filter),
    /// Declared last: dropped after the pointers above are gone.
    _library: libloading::Library,
}

impl Api {
    /// Loads the library at `path` (a file name alone searches the system's
    /// library path) and resolves every entry point.
    pub(crate) fn load(path: &Path) -> Result<Api, String> {
        // SAFETY: loading runs the library's initialisers; OIDN's only set
        // up its own state (no global side effects on ours).
        let library = unsafe { libloading::Library::new(path) }.map_err(|e| e.to_string())?;
        macro_rules! sym {
            ($name:literal) => {
                // SAFETY: the symbol is OIDN 2's function of this name, and
                // the field it is stored in has that function's C signature
                // (oidn.h); the pointer lives no longer than `library`,
                // which is stored in the same struct and dropped last.
                *unsafe { library.get(concat!($name, "\0").as_bytes()) }.map_err(|e| format!("{}: {e}", $name))?
            };
        }
        Ok(Api {
            new_device: sym!("oidnNewDevice"),
            set_device_int: sym!("oidnSetDeviceInt"),
            commit_device: sym!("oidnCommitDevice"),
            get_device_error: sym!("oidnGetDeviceError"),
            release_device: sym!("oidnReleaseDevice"),
            new_filter: sym!("oidnNewFilter"),
            set_shared_filter_image: sym!("oidnSetSharedFilterImage"),
            set_filter_bool: sym!("oidnSetFilterBool"),
            set_filter_int: sym!("oidnSetFilterInt"),
            set_filter_progress_monitor: sym!("oidnSetFilterProgressMonitorFunction"),
            commit_filter: sym!("oidnCommitFilter"),
            execute_filter: sym!("oidnExecuteFilter"),
            release_filter: sym!("oidnReleaseFilter"),
            _library: library,
        })
    }
}

/// A committed CPU device.
pub(crate) struct OidnDevice {
    api: Api,
    device: Device,
}

// SAFETY: an OIDN device may be used from any thread, one call at a time
// (oidn.h: objects are thread-safe except for concurrent modification);
// `Denoiser` serialises every use behind a mutex.
unsafe impl Send for OidnDevice {}

/// The images of one filter run, each `width * height` RGB floats.
pub(crate) struct Images<'a> {
    pub width: usize,
    pub height: usize,
    pub color: &'a [f32],
    pub albedo: Option<&'a [f32]>,
    pub normal: Option<&'a [f32]>,
    pub output: &'a mut [f32],
}

fn cstr(s: &str) -> CString {
    // Only the literals below are passed: none holds a NUL.
    CString::new(s).unwrap_or_default()
}

impl OidnDevice {
    /// A CPU device with `threads` worker threads (0: OIDN's default).
    pub(crate) fn new(api: Api, threads: usize) -> Result<OidnDevice, String> {
        // SAFETY: oidnNewDevice takes a device type and returns a handle or
        // null; null is checked.
        let device = unsafe { (api.new_device)(DEVICE_TYPE_CPU) };
        if device.is_null() {
            return Err("oidnNewDevice returned no CPU device".to_owned());
        }
        let dev = OidnDevice { api, device };
        if threads > 0 {
            let n = c_int::try_from(threads).unwrap_or(c_int::MAX);
            // SAFETY: a live device handle and a NUL-terminated name.
            unsafe { (dev.api.set_device_int)(dev.device, cstr("numThreads").as_ptr(), n) };
        }
        // SAFETY: a live device handle.
        unsafe { (dev.api.commit_device)(dev.device) };
        dev.check()?;
        Ok(dev)
    }

    /// The device's pending error, if any, as a message (and clears it).
    fn check(&self) -> Result<(), String> {
        self.check_code().map_err(|(_, message)| message)
    }

    /// [`OidnDevice::check`] with OIDN's error code.
    fn check_code(&self) -> Result<(), (c_int, String)> {
        let mut message: *const c_char = std::ptr::null();
        // SAFETY: a live device handle and a valid out-pointer; the message
        // OIDN returns is a NUL-terminated string valid until the next call
        // on the device, and is copied at once.
        let code = unsafe { (self.api.get_device_error)(self.device, &mut message) };
        if code == ERROR_NONE {
            return Ok(());
        }
        let text = if message.is_null() {
            String::new()
        } else {
            // SAFETY: see above.
            unsafe { CStr::from_ptr(message) }.to_string_lossy().into_owned()
        };
        Err((code, format!("OIDN error {code}: {text}")))
    }

    /// Runs the `RT` filter (HDR input) on `images`; gives up when
    /// `cancel` (checked at OIDN's progress reports) reads true.
    pub(crate) fn run_rt(
        &self,
        images: Images<'_>,
        quality: c_int,
        cancel: Option<&AtomicBool>,
    ) -> Result<(), RunError> {
        let n = images.width * images.height * 3;
        let sizes_ok = images.color.len() == n
            && images.output.len() == n
            && images.albedo.is_none_or(|a| a.len() == n)
            && images.normal.is_none_or(|a| a.len() == n);
        if !sizes_ok || n == 0 {
            return Err(RunError::Failed("image sizes do not match".to_owned()));
        }
        // SAFETY: a live device handle and a NUL-terminated filter type;
        // null is checked.
        let filter = unsafe { (self.api.new_filter)(self.device, cstr("RT").as_ptr()) };
        if filter.is_null() {
            self.check()?;
            return Err(RunError::Failed("oidnNewFilter(\"RT\") returned no filter".to_owned()));
        }
        let release = FilterGuard { api: &self.api, filter };
        let stride = 3 * std::mem::size_of::<f32>();
        let set = |name: &str, data: *mut f32| {
            // SAFETY: a live filter; `data` points at `width * height`
            // packed float3 pixels (lengths checked above) that stay
            // borrowed until after the synchronous execute below; OIDN
            // reads inputs and writes only "output".
            unsafe {
                (self.api.set_shared_filter_image)(
                    release.filter,
                    cstr(name).as_ptr(),
                    data.cast(),
                    FORMAT_FLOAT3,
                    images.width,
                    images.height,
                    0,
                    stride,
                    stride * images.width,
                )
            }
        };
        // OIDN never writes an input image; the casts to *mut follow its API.
        set("color", images.color.as_ptr().cast_mut());
        if let Some(a) = images.albedo {
            set("albedo", a.as_ptr().cast_mut());
        }
        if let Some(nrm) = images.normal {
            set("normal", nrm.as_ptr().cast_mut());
        }
        set("output", images.output.as_mut_ptr());
        // SAFETY: a live filter and NUL-terminated parameter names.
        unsafe {
            (self.api.set_filter_bool)(release.filter, cstr("hdr").as_ptr(), true);
            (self.api.set_filter_int)(release.filter, cstr("quality").as_ptr(), quality);
        }
        if let Some(flag) = cancel {
            // SAFETY: a live filter; `keep_going` has the monitor's C
            // signature and reads the user pointer only as the
            // `&AtomicBool` given here, which is borrowed for this whole
            // call and so outlives the synchronous execute below and the
            // filter (released by `release` before this returns).
            unsafe {
                (self.api.set_filter_progress_monitor)(
                    release.filter,
                    Some(keep_going),
                    std::ptr::from_ref(flag).cast_mut().cast(),
                );
            }
        }
        // SAFETY: a live filter.
        unsafe { (self.api.commit_filter)(release.filter) };
        self.check()?;
        // SAFETY: a committed filter whose images are alive (see `set`);
        // execution is synchronous.
        unsafe { (self.api.execute_filter)(release.filter) };
        match self.check_code() {
            Err((ERROR_CANCELLED, _)) => Err(RunError::Cancelled),
            Err((_, message)) => Err(RunError::Failed(message)),
            Ok(()) => Ok(()),
        }
    }
}

/// The progress monitor: goes on while the flag behind `user` reads false.
unsafe extern "C" fn keep_going(user: *mut c_void, _progress: f64) -> bool {
    // SAFETY: `run_rt` registers this function only with a pointer to an
    // `AtomicBool` that outlives the filter (see there); an atomic may be
    // read from whichever thread OIDN calls this on.
    let cancel = unsafe { &*user.cast_const().cast::<AtomicBool>() };
    !cancel.load(Ordering::Relaxed)
}

/// Releases a filter when dropped.
struct FilterGuard<'a> {
    api: &'a Api,
    filter: Filter,
}

impl Drop for FilterGuard<'_> {
    fn drop(&mut self) {
        // SAFETY: the filter was created by this device and is released
        // once, here.
        unsafe { (self.api.release_filter)(self.filter) };
    }
}

impl Drop for OidnDevice {
    fn drop(&mut self) {
        // SAFETY: the device handle is live and released once, here; every
        // filter made from it was released already (FilterGuard).
        unsafe { (self.api.release_device)(self.device) };
    }
}
