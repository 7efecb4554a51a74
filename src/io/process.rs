//! Child processes (renderers, probes, model servers) that never outlive their use: each starts
//! in a process group of its own, and the whole group is killed when the child ends, times out
//! or the run is interrupted, so that what a renderer left running in the background goes with
//! it. A process that leaves the group (`setsid`, a daemon) escapes this, as it escapes a
//! terminal's Ctrl-C. libc is used for what std does not offer: killing a group, and seeing an
//! exit without reaping (a reaped child's id could name another process's group).

use std::process::{Child, Command};
use std::sync::Mutex;

/// Process groups alive now, by their leader's id, and whether the run was interrupted (a
/// group started after that is killed at once).
static GROUPS: Mutex<(Vec<u32>, bool)> = Mutex::new((Vec::new(), false));

/// A child in a process group of its own; its group is killed when this guard drops.
#[derive(Debug)]
pub struct Group {
    /// The child, the leader of its group (take its pipes; reap it only through the guard).
    pub child: Child,
    /// The leader was reaped: its id may name another process now, so it is not killed again.
    reaped: bool,
}

/// Starts `cmd` in a new process group. Outside the terminal's foreground group it no longer
/// gets the terminal's Ctrl-C: furnace's handler kills the group through [`kill_all`].
pub fn spawn(cmd: &mut Command) -> std::io::Result<Group> {
    #[cfg(unix)]
    std::os::unix::process::CommandExt::process_group(cmd, 0);
    // the lock is held from the spawn to the record, so an interrupt sees every group
    let mut groups = lock();
    let child = cmd.spawn()?;
    groups.0.push(child.id());
    let interrupted = groups.1;
    drop(groups);
    let mut group = Group {
        child,
        reaped: false,
    };
    if interrupted {
        let _ = group.kill_and_wait();
        return Err(std::io::Error::new(
            std::io::ErrorKind::Interrupted,
            "the run was interrupted",
        ));
    }
    Ok(group)
}

impl Group {
    /// Whether the leader has exited, without reaping it where the system allows: while it is
    /// unreaped its id, the group's, cannot be reused.
    pub fn exited(&mut self) -> std::io::Result<bool> {
        if self.reaped {
            return Ok(true);
        }
        #[cfg(target_os = "linux")]
        {
            // SAFETY: waitid writes only into `info`, a zeroed siginfo_t we own; P_PID with
            // our own unreaped child's id and WNOWAIT leaves the child unreaped.
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
            // elsewhere the exit is seen by reaping: the group is then not killed (its id may
            // be reused), so what the leader left running is left
            // (under the lock, so that kill_all never signals the id once it is reaped)
            let mut groups = lock();
            let done = self.child.try_wait()?.is_some();
            if done {
                self.reaped = true;
                if let Some(i) = groups.0.iter().rposition(|p| *p == self.child.id()) {
                    groups.0.swap_remove(i);
                }
            }
            Ok(done)
        }
    }

    /// Kills every process left in the group (the leader too, if it still runs) and reaps the
    /// leader; returns its exit status.
    pub fn kill_and_wait(&mut self) -> std::io::Result<std::process::ExitStatus> {
        if !self.reaped {
            // killed and forgotten under one lock, so kill_all never signals a reaped id
            let mut groups = lock();
            kill_group(self.child.id());
            let _ = self.child.kill();
            if let Some(i) = groups.0.iter().rposition(|p| *p == self.child.id()) {
                groups.0.swap_remove(i);
            }
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

/// Kills every group still alive, and every group started from now on; called on interrupt
/// and on any exit that skips the guards' drops.
pub fn kill_all() {
    let mut groups = lock();
    groups.1 = true;
    for id in groups.0.drain(..) {
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

/// The list, even if a thread panicked while holding it.
fn lock() -> std::sync::MutexGuard<'static, (Vec<u32>, bool)> {
    GROUPS.lock().unwrap_or_else(|e| e.into_inner())
}

#[cfg(all(test, target_os = "linux"))]
mod tests {
    use super::*;
    use std::time::{Duration, Instant};

    /// A background child of the leader holds the output pipe open; killing the group ends it,
    /// so reading the pipe to its end returns at once (read in a thread: without the group
    /// kill it would wait for the `sleep`).
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
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let mut text = String::new();
            let _ = std::io::Read::read_to_string(&mut out, &mut text);
            let _ = tx.send(text);
        });
        let text = rx.recv_timeout(Duration::from_secs(10)).unwrap();
        assert_eq!(text, "started\n");
        assert!(!lock().0.contains(&g.child.id()));
        // once reaped, the exit is known without asking the system again
        assert!(g.exited().unwrap());
    }
}
