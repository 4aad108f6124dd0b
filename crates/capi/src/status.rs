//! Status codes, the thread's last error message, and the boundary every exported function
//! goes through: its body runs under `catch_unwind`, its error becomes a status code and a
//! message, and nothing unwinds into C.

use std::cell::RefCell;
use std::ffi::{c_char, CStr, CString};
use std::panic::{catch_unwind, AssertUnwindSafe};

use tilegraph_graph::GraphError;
use tilegraph_passes::RenderError;
use tilegraph_profile::ProfileError;
use tilegraph_scene::SceneError;
use tilegraph_vk::VkError;

/// What a call did. `TG_STATUS_OK` is zero; every other value leaves a message for
/// `tg_last_error`.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TgStatus {
    Ok = 0,
    /// A pointer argument that must not be null was null.
    NullPointer = 1,
    /// A zero handle, a destroyed one, one of another kind, or one made on another thread.
    InvalidHandle = 2,
    /// A value out of range: a zero size, an unknown enum value, a string that is not UTF-8,
    /// an index past the end, an image that does not match the renderer.
    InvalidArgument = 3,
    /// An array pointer not aligned for its element type.
    Misaligned = 4,
    /// The object still has users (a context with renderers, a scene a renderer draws).
    InUse = 5,
    /// The device lacks a feature the request needs (the message names it and what wants it).
    MissingFeature = 6,
    /// Out of host or device memory, or past the context's memory budget: the frame failed
    /// cleanly; free memory and record the next one.
    OutOfMemory = 7,
    /// The device was lost: destroy the renderers, the context, then the device.
    DeviceLost = 8,
    /// Another Vulkan error (the message names the call and the VkResult).
    Vulkan = 9,
    /// The scene's data or file is invalid (the message names the element).
    Scene = 10,
    /// The frame graph does not compile (the message names the pass and resource).
    Graph = 11,
    /// No such profile, or a profile file is invalid.
    Profile = 12,
    /// A bug in tilegraph caught at the boundary (a panic); the object the call used is gone.
    Internal = 13,
}

impl TgStatus {
    pub const ALL: [TgStatus; 14] = [
        TgStatus::Ok,
        TgStatus::NullPointer,
        TgStatus::InvalidHandle,
        TgStatus::InvalidArgument,
        TgStatus::Misaligned,
        TgStatus::InUse,
        TgStatus::MissingFeature,
        TgStatus::OutOfMemory,
        TgStatus::DeviceLost,
        TgStatus::Vulkan,
        TgStatus::Scene,
        TgStatus::Graph,
        TgStatus::Profile,
        TgStatus::Internal,
    ];

    /// The C name (`TG_STATUS_...`), NUL-terminated.
    pub const fn name(self) -> &'static CStr {
        match self {
            TgStatus::Ok => c"TG_STATUS_OK",
            TgStatus::NullPointer => c"TG_STATUS_NULL_POINTER",
            TgStatus::InvalidHandle => c"TG_STATUS_INVALID_HANDLE",
            TgStatus::InvalidArgument => c"TG_STATUS_INVALID_ARGUMENT",
            TgStatus::Misaligned => c"TG_STATUS_MISALIGNED",
            TgStatus::InUse => c"TG_STATUS_IN_USE",
            TgStatus::MissingFeature => c"TG_STATUS_MISSING_FEATURE",
            TgStatus::OutOfMemory => c"TG_STATUS_OUT_OF_MEMORY",
            TgStatus::DeviceLost => c"TG_STATUS_DEVICE_LOST",
            TgStatus::Vulkan => c"TG_STATUS_VULKAN",
            TgStatus::Scene => c"TG_STATUS_SCENE",
            TgStatus::Graph => c"TG_STATUS_GRAPH",
            TgStatus::Profile => c"TG_STATUS_PROFILE",
            TgStatus::Internal => c"TG_STATUS_INTERNAL",
        }
    }
}

/// A failed call: its status and the message `tg_last_error` returns.
#[derive(Debug)]
pub struct Failure {
    pub status: TgStatus,
    pub message: String,
}

impl Failure {
    pub fn new(status: TgStatus, message: impl Into<String>) -> Self {
        Failure {
            status,
            message: message.into(),
        }
    }

    pub fn invalid(message: impl Into<String>) -> Self {
        Failure::new(TgStatus::InvalidArgument, message)
    }
}

impl From<VkError> for Failure {
    fn from(e: VkError) -> Self {
        let status = if e.is_out_of_memory() {
            TgStatus::OutOfMemory
        } else if e.is_device_lost() {
            TgStatus::DeviceLost
        } else {
            match &e {
                VkError::MissingRequired { .. } => TgStatus::MissingFeature,
                VkError::Profile(_) => TgStatus::Profile,
                VkError::Invalid { .. } => TgStatus::InvalidArgument,
                _ => TgStatus::Vulkan,
            }
        };
        Failure::new(status, e.to_string())
    }
}

impl From<RenderError> for Failure {
    fn from(e: RenderError) -> Self {
        match e {
            RenderError::Vk(v) => v.into(),
            RenderError::Graph(g) => g.into(),
            RenderError::MissingFeature { .. } => {
                Failure::new(TgStatus::MissingFeature, e.to_string())
            }
            other => Failure::invalid(other.to_string()),
        }
    }
}

impl From<GraphError> for Failure {
    fn from(e: GraphError) -> Self {
        Failure::new(TgStatus::Graph, e.to_string())
    }
}

impl From<SceneError> for Failure {
    fn from(e: SceneError) -> Self {
        let status = match e {
            SceneError::StaleHandle { .. } => TgStatus::InvalidHandle,
            SceneError::MeshInUse { .. } => TgStatus::InUse,
            _ => TgStatus::Scene,
        };
        Failure::new(status, e.to_string())
    }
}

impl From<ProfileError> for Failure {
    fn from(e: ProfileError) -> Self {
        Failure::new(TgStatus::Profile, e.to_string())
    }
}

thread_local! {
    /// The last failure's message on this thread, NUL-terminated for C.
    static LAST_ERROR: RefCell<CString> = RefCell::new(CString::default());
}

fn set_last_error(message: &str) {
    // Interior NULs would cut the message short in C: shown as spaces.
    let text = CString::new(message.replace('\0', " ")).unwrap_or_default();
    LAST_ERROR.with(|e| *e.borrow_mut() = text);
}

/// The message of this thread's last failed call (empty after a success, or before any
/// call). The pointer stays valid until the next tilegraph call on this thread.
#[no_mangle]
pub extern "C" fn tg_last_error() -> *const c_char {
    LAST_ERROR.with(|e| e.borrow().as_ptr())
}

/// The name of a status code (`"TG_STATUS_OK"`...); `"TG_STATUS_UNKNOWN"` for a value that is
/// none of them. A static string.
#[no_mangle]
pub extern "C" fn tg_status_name(status: u32) -> *const c_char {
    TgStatus::ALL
        .into_iter()
        .find(|s| *s as u32 == status)
        .map_or(c"TG_STATUS_UNKNOWN".as_ptr(), |s| s.name().as_ptr())
}

/// Checks the library's panic boundary: runs a deliberate internal failure (a panic) inside it
/// and returns what any function would after a bug in tilegraph — TG_STATUS_INTERNAL, with a
/// message. An engine calls it once in its tests: a build of tilegraph with `panic = "abort"`
/// cannot catch panics and aborts here instead of returning.
#[no_mangle]
pub extern "C" fn tg_check_panic_boundary() -> TgStatus {
    boundary("tg_check_panic_boundary", || {
        std::panic::panic_any("the deliberate failure of tg_check_panic_boundary")
    })
}

/// Runs an exported function's body: its failure (or a panic) becomes a status and this
/// thread's last error; a success clears the last error.
pub fn boundary(function: &str, body: impl FnOnce() -> Result<(), Failure>) -> TgStatus {
    match catch_unwind(AssertUnwindSafe(body)) {
        Ok(Ok(())) => {
            LAST_ERROR.with(|e| {
                let mut e = e.borrow_mut();
                if !e.as_bytes().is_empty() {
                    *e = CString::default();
                }
            });
            TgStatus::Ok
        }
        Ok(Err(f)) => {
            log::debug!("{function}: {}", f.message);
            set_last_error(&format!("{function}: {}", f.message));
            f.status
        }
        Err(panic) => {
            let what = panic
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "a panic".into());
            log::error!("{function}: internal error: {what}");
            set_last_error(&format!(
                "{function}: internal error (a bug in tilegraph, please report it): {what}"
            ));
            TgStatus::Internal
        }
    }
}

/// `ptr` as a reference, or a `NullPointer` failure naming the argument.
///
/// # Safety
/// A non-null `ptr` points to a valid `T` for the call (the C caller's contract).
pub unsafe fn arg<'a, T>(ptr: *const T, name: &str) -> Result<&'a T, Failure> {
    check_pointer(ptr, name)?;
    // SAFETY: non-null and aligned (checked); valid by the caller's contract.
    Ok(unsafe { &*ptr })
}

/// `ptr` as a mutable reference (an out-parameter), or a `NullPointer` failure.
///
/// # Safety
/// A non-null `ptr` points to writable memory for a `T`.
pub unsafe fn out<'a, T>(ptr: *mut T, name: &str) -> Result<&'a mut T, Failure> {
    check_pointer(ptr, name)?;
    // SAFETY: as for `arg`.
    Ok(unsafe { &mut *ptr })
}

fn check_pointer<T>(ptr: *const T, name: &str) -> Result<(), Failure> {
    if ptr.is_null() {
        return Err(Failure::new(
            TgStatus::NullPointer,
            format!("`{name}` is null"),
        ));
    }
    if ptr.cast::<u8>().align_offset(std::mem::align_of::<T>()) != 0 {
        return Err(misaligned::<T>(ptr, name));
    }
    Ok(())
}

fn misaligned<T>(ptr: *const T, name: &str) -> Failure {
    Failure::new(
        TgStatus::Misaligned,
        format!(
            "`{name}` ({ptr:p}) is not aligned to {} bytes for {}",
            std::mem::align_of::<T>(),
            short_type_name::<T>()
        ),
    )
}

fn short_type_name<T>() -> &'static str {
    let full = std::any::type_name::<T>();
    full.rsplit("::").next().unwrap_or(full)
}

/// An array argument of `count` elements: `count` zero is an empty slice (the pointer may then
/// be null); otherwise the pointer must be non-null and aligned.
///
/// # Safety
/// A non-null `ptr` points to `count` valid elements.
pub unsafe fn array<'a, T>(ptr: *const T, count: usize, name: &str) -> Result<&'a [T], Failure> {
    if count == 0 {
        return Ok(&[]);
    }
    if ptr.is_null() {
        return Err(Failure::new(
            TgStatus::NullPointer,
            format!("`{name}` is null but its count is {count}"),
        ));
    }
    if ptr.cast::<u8>().align_offset(std::mem::align_of::<T>()) != 0 {
        return Err(misaligned::<T>(ptr, name));
    }
    if count
        .checked_mul(std::mem::size_of::<T>())
        .is_none_or(|b| b > isize::MAX as usize)
    {
        return Err(Failure::invalid(format!(
            "`{name}`: {count} elements overflow the address space"
        )));
    }
    // SAFETY: non-null, aligned, size in range (checked); valid by the caller's contract.
    Ok(unsafe { std::slice::from_raw_parts(ptr, count) })
}

/// An output array of `count` elements: `count` zero is an empty slice (the pointer may then be
/// null); otherwise the pointer must be non-null and aligned.
///
/// # Safety
/// A non-null `ptr` points to `count` writable elements.
pub unsafe fn out_array<'a, T>(
    ptr: *mut T,
    count: usize,
    name: &str,
) -> Result<&'a mut [T], Failure> {
    // SAFETY: the caller's contract; `array` checks null, alignment and size.
    let checked = unsafe { array(ptr.cast_const(), count, name) }?;
    if checked.is_empty() {
        return Ok(&mut []);
    }
    // SAFETY: non-null, aligned, in range (checked above); writable by the caller's contract.
    Ok(unsafe { std::slice::from_raw_parts_mut(ptr, count) })
}

/// A NUL-terminated UTF-8 string argument.
///
/// # Safety
/// A non-null `ptr` points to a NUL-terminated string.
pub unsafe fn string<'a>(ptr: *const c_char, name: &str) -> Result<&'a str, Failure> {
    if ptr.is_null() {
        return Err(Failure::new(
            TgStatus::NullPointer,
            format!("`{name}` is null"),
        ));
    }
    // SAFETY: non-null, NUL-terminated by the caller's contract.
    unsafe { CStr::from_ptr(ptr) }
        .to_str()
        .map_err(|e| Failure::invalid(format!("`{name}` is not UTF-8: {e}")))
}

/// An optional string argument: null is `None`.
///
/// # Safety
/// As for [`string`].
pub unsafe fn optional_string<'a>(
    ptr: *const c_char,
    name: &str,
) -> Result<Option<&'a str>, Failure> {
    if ptr.is_null() {
        return Ok(None);
    }
    // SAFETY: as above.
    unsafe { string(ptr, name) }.map(Some)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// No input reaches a panic by design; the boundary still turns one (a bug) into
    /// TG_STATUS_INTERNAL with a message, and a later success clears the message.
    #[test]
    fn a_panic_becomes_internal_and_never_unwinds() {
        let status = boundary("tg_test", || panic!("invariant broken"));
        assert_eq!(status, TgStatus::Internal);
        // SAFETY: tg_last_error returns a NUL-terminated string owned by this thread.
        let message = unsafe { CStr::from_ptr(tg_last_error()) }
            .to_string_lossy()
            .into_owned();
        assert!(
            message.contains("tg_test") && message.contains("invariant broken"),
            "{message}"
        );
        assert_eq!(boundary("tg_test", || Ok(())), TgStatus::Ok);
        // SAFETY: as above.
        assert!(unsafe { CStr::from_ptr(tg_last_error()) }
            .to_bytes()
            .is_empty());
    }

    #[test]
    fn every_status_has_its_c_name() {
        for s in TgStatus::ALL {
            // SAFETY: static NUL-terminated strings.
            let name = unsafe { CStr::from_ptr(tg_status_name(s as u32)) };
            assert!(name.to_str().is_ok_and(|n| n.starts_with("TG_STATUS_")));
        }
        // SAFETY: as above.
        let unknown = unsafe { CStr::from_ptr(tg_status_name(999)) };
        assert_eq!(unknown.to_str(), Ok("TG_STATUS_UNKNOWN"));
    }
}
