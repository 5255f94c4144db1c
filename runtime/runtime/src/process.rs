//! Child processes that never outlive their parent, signals, and a key handed to a child: the
//! few operating-system calls std does not offer, in one audited place (the workspace denies
//! `unsafe` everywhere else).
#![allow(unsafe_code)]

use std::io::Write as _;
use std::os::unix::process::CommandExt as _;
use std::process::{Command, Stdio};

use armor_module_api::auth::ENV_KEY_FD;

/// Makes the child its own process group (so a terminal's Ctrl-C reaches only the supervisor,
/// which then stops children in order) and has the kernel kill it when the supervisor dies,
/// even by SIGKILL, so no module outlives its run.
pub fn die_with_parent(command: &mut Command) {
    // SAFETY: the closure runs between fork and exec and only makes async-signal-safe system
    // calls (setpgid, prctl, getppid), touching no memory of the parent.
    let parent = std::process::id() as libc::pid_t;
    unsafe {
        command.pre_exec(move || {
            if libc::setpgid(0, 0) != 0 || libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGKILL) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            // The parent may have died before prctl took effect: then nobody would kill us.
            if libc::getppid() != parent {
                return Err(std::io::Error::other("the supervisor died during start-up"));
            }
            Ok(())
        });
    }
}

/// Sends a signal to a process; a process that is already gone is not an error.
pub fn kill(pid: libc::pid_t, signal: libc::c_int) {
    // SAFETY: kill(2) has no memory-safety preconditions.
    unsafe {
        libc::kill(pid, signal);
    }
}

/// Hands `text` (a key) to the child `command` starts through a pipe that becomes its
/// standard input, named by `ARMOR_KEY_FD=0`: the child reads it and closes it at start, and
/// nothing of it shows in `/proc/PID/environ` or `cmdline`. The pipe holds the few bytes
/// until the child reads them, so they are written before it starts.
pub fn hand_over(command: &mut Command, text: &str) -> std::io::Result<()> {
    let (reader, mut writer) = std::io::pipe()?;
    writer.write_all(text.as_bytes())?;
    drop(writer);
    command.stdin(Stdio::from(reader)).env(ENV_KEY_FD, "0");
    Ok(())
}
