//! Temporary files and folders that must not outlive the process: each lives in a [`Pending`]
//! guard that removes it when dropped, and [`remove_all`] removes every live one (the CLI calls
//! it from its Ctrl-C / SIGTERM handler before exiting).

use std::path::{Path, PathBuf};
use std::sync::Mutex;

static PENDING: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// A temporary file or folder, removed when the guard drops or the process is interrupted.
#[derive(Debug)]
pub struct Pending(PathBuf);

impl Pending {
    /// Registers `path` (which need not exist yet) for removal.
    pub fn new(path: PathBuf) -> Pending {
        lock().push(path.clone());
        Pending(path)
    }

    /// The registered path.
    pub fn path(&self) -> &Path {
        &self.0
    }
}

impl Drop for Pending {
    fn drop(&mut self) {
        remove(&self.0);
        let mut list = lock();
        if let Some(i) = list.iter().rposition(|p| *p == self.0) {
            list.swap_remove(i);
        }
    }
}

/// Removes every registered path that still exists; called on interrupt.
pub fn remove_all() {
    for p in lock().drain(..) {
        remove(&p);
    }
}

fn remove(p: &Path) {
    match std::fs::symlink_metadata(p) {
        Ok(m) if m.is_dir() => {
            let _ = std::fs::remove_dir_all(p);
        }
        Ok(_) => {
            let _ = std::fs::remove_file(p);
        }
        Err(_) => {}
    }
}

/// The list, even if a thread panicked while holding it (it stays a valid list).
fn lock() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    PENDING.lock().unwrap_or_else(|e| e.into_inner())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn guards_remove_on_drop_and_remove_all_removes_the_live_ones() {
        let base = std::env::temp_dir().join(format!("furnace-cleanup-{}", std::process::id()));
        let (a, b) = (base.join("a"), base.join("b.txt"));
        std::fs::create_dir_all(&a).unwrap();
        std::fs::write(a.join("x"), "x").unwrap();
        std::fs::write(&b, "b").unwrap();
        let ga = Pending::new(a.clone());
        {
            let _gb = Pending::new(b.clone());
        }
        assert!(!b.exists() && a.exists());
        remove_all();
        assert!(!a.exists());
        drop(ga);
        let _ = std::fs::remove_dir_all(&base);
    }
}
