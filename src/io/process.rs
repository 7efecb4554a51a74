//! Child processes (renderers, probes, model servers) that never outlive their use: each starts
//! in a process group of its own, and the whole group is killed when the child ends, times out
//! or the run is interrupted, so that what a renderer started in the background goes with it.
//! libc is used for what std does not offer: killing a group, and seeing an exit without
//! reaping (a reaped child's id could name another process's group).

use std::process::{Child, Command};
use std::sync::Mutex;

/// Process groups alive now, by their leader's id (killed on interrupt by [`kill_all`]).
static GROUPS: Mutex<Vec<u32>> = Mutex::new(Vec::new());

/// A child in a process group of its own; its group is killed when this guard drops.
#[derive(Debug)]
pub struct Group {
    /// The child, the leader of its group.
    pub child: Child,
    /// The leader was reaped: its id may name another process now, so it is not killed again.
    reaped: bool,
}

/// Starts `cmd` in a new process group (so a terminal's Ctrl-C reaches furnace, whose handler
/// kills the group through [`kill_all`]).
pub fn spawn(cmd: &mut Command) -> std::io::Result<Group> {
    #[cfg(unix)]
    std::os::unix::process::CommandExt::process_group(cmd, 0);
    let child = cmd.spawn()?;
    lock().push(child.id());
    Ok(Group {
        child,
        reaped: false,
    })
}

impl Group {
    /// Whether the leader has exited, without reaping it: while it is unreaped its id, the
    /// group's, cannot be reused.
    pub fn exited(&mut self) -> std::io::Result<bool> {
        #[cfg(target_os = "linux")]
        {
            // SAFETY: waitid writes only into `info`, a zeroed siginfo_t we own; P_PID with
            // our own child's id and WNOWAIT leaves the child unreaped.
            let mut info: libc::siginfo_t = unsafe { std::mem::zeroed() };
            let r = unsafe {
                libc::waitid(
                    libc::P_PID,
                    self.child.id(),
                    &mut info,
                    libc::WEXITED | libc::WNOHANG | libc::WNOWAIT,
                )
            };
            if r != 0 {
                return Err(std::io::Error::last_os_error());
            }
            // SAFETY: waitid filled `info` (si_pid stays 0 when no child has exited)
            Ok(unsafe { info.si_pid() } != 0)
        }
        #[cfg(not(target_os = "linux"))]
        {
            Ok(self.child.try_wait()?.is_some())
        }
    }

    /// Kills every process left in the group (the leader too, if it still runs) and reaps the
    /// leader; returns its exit status.
    pub fn kill_and_wait(&mut self) -> std::io::Result<std::process::ExitStatus> {
        if !self.reaped {
            kill_group(self.child.id());
            let _ = self.child.kill();
            forget(self.child.id());
            self.reaped = true;
        }
        // std keeps the status of a child already waited for
        self.child.wait()
    }
}

impl Drop for Group {
    fn drop(&mut self) {
        let _ = self.kill_and_wait();
    }
}

/// Kills every group still alive; called on interrupt.
pub fn kill_all() {
    for id in lock().drain(..) {
        kill_group(id);
    }
}

fn kill_group(leader: u32) {
    #[cfg(unix)]
    if let Ok(id) = i32::try_from(leader) {
        // SAFETY: kill has no memory effects; -id names the group our child leads, whose id is
        // reserved while the leader is unreaped (callers kill before they reap)
        unsafe {
            libc::kill(-id, libc::SIGKILL);
        }
    }
}

fn forget(leader: u32) {
    let mut list = lock();
    if let Some(i) = list.iter().rposition(|p| *p == leader) {
        list.swap_remove(i);
    }
}

/// The list, even if a thread panicked while holding it.
fn lock() -> std::sync::MutexGuard<'static, Vec<u32>> {
    GROUPS.lock().unwrap_or_else(|e| e.into_inner())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::{Duration, Instant};

    /// A background child of the leader holds the output pipe open; killing the group ends it,
    /// so reading the pipe to its end returns at once.
    #[test]
    fn killing_the_group_ends_what_the_child_left_in_the_background() {
        let mut cmd = Command::new("sh");
        cmd.args(["-c", "sleep 1000 & echo started"])
            .stdout(std::process::Stdio::piped());
        let mut g = spawn(&mut cmd).unwrap();
        let mut out = g.child.stdout.take().unwrap();
        let start = Instant::now();
        while !g.exited().unwrap() {
            assert!(start.elapsed() < Duration::from_secs(10));
            std::thread::sleep(Duration::from_millis(10));
        }
        assert!(g.kill_and_wait().unwrap().success());
        let mut text = String::new();
        std::io::Read::read_to_string(&mut out, &mut text).unwrap();
        assert_eq!(text, "started\n");
        assert!(start.elapsed() < Duration::from_secs(10));
        assert!(!lock().contains(&g.child.id()));
    }
}
