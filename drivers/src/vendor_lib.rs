//! Loading a proprietary vendor library at run time (OpenHaptics' `libHD.so`, Force
//! Dimension's `libdhd.so`): which files to try, `dlopen` of the first that opens, and its
//! symbols by name. Nothing links against the vendors' libraries; each driver declares only the
//! functions it calls (its `ffi` module) and resolves them here.

use std::ffi::{c_void, CStr, CString};
use std::path::{Path, PathBuf};

/// The libraries to try, in order: the environment variable `env` if set and not empty, else
/// `configured` if given (the daemon config's key), else `defaults`.
pub(crate) fn candidates(env: &str, configured: Option<&Path>, defaults: &[&str]) -> Vec<PathBuf> {
    match std::env::var_os(env).filter(|v| !v.is_empty()) {
        Some(v) => vec![PathBuf::from(v)],
        None => match configured {
            Some(p) => vec![p.to_path_buf()],
            None => defaults.iter().map(PathBuf::from).collect(),
        },
    }
}

/// A library `dlopen`ed for the life of the process (a vendor's threads may outlive any one
/// device).
pub(crate) struct Library {
    handle: *mut c_void,
    /// The file that was loaded.
    pub path: PathBuf,
}

impl Library {
    /// The address of symbol `name`, or `None` if the library lacks it.
    pub fn symbol(&self, name: &str) -> Option<*mut c_void> {
        let c = CString::new(name).expect("symbol names have no NUL");
        // SAFETY: valid handle from dlopen and a valid C string.
        let p = unsafe { libc::dlsym(self.handle, c.as_ptr()) };
        (!p.is_null()).then_some(p)
    }
}

/// Opens the first of `candidates` that `dlopen` accepts and gives it to `resolve` (which
/// takes the symbols it needs); the API it builds lives for the rest of the process. Err: one
/// reason per candidate tried (the loader's), or `resolve`'s error for the library that opened.
pub(crate) fn load<T>(
    candidates: &[PathBuf],
    resolve: impl FnOnce(&Library) -> Result<T, String>,
) -> Result<&'static T, String> {
    let mut tried = Vec::new();
    for path in candidates {
        let Ok(c_path) = CString::new(path.as_os_str().as_encoded_bytes()) else {
            tried.push(format!("{} (contains a NUL byte)", path.display()));
            continue;
        };
        // SAFETY: valid C string; RTLD_NOW resolves everything now so a broken library fails
        // here, not in the haptic loop.
        let handle = unsafe { libc::dlopen(c_path.as_ptr(), libc::RTLD_NOW | libc::RTLD_LOCAL) };
        if handle.is_null() {
            tried.push(dlerror_text());
            continue;
        }
        let library = Library {
            handle,
            path: path.clone(),
        };
        return resolve(&library).map(|api| &*Box::leak(Box::new(api)));
    }
    Err(tried.join("; "))
}

fn dlerror_text() -> String {
    // SAFETY: dlerror returns NULL or a NUL-terminated string valid until the next dl* call.
    let e = unsafe { libc::dlerror() };
    if e.is_null() {
        "unknown dlopen error".into()
    } else {
        // SAFETY: checked non-null above.
        unsafe { CStr::from_ptr(e) }.to_string_lossy().into_owned()
    }
}
