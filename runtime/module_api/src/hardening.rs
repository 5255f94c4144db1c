//! What a module process does for itself, first thing, so that its siblings of the same user
//! cannot take its key: it makes itself non-dumpable, and it reads its key from an inherited
//! descriptor and closes it.
//!
//! Non-dumpable (`prctl(PR_SET_DUMPABLE, 0)`): the kernel then gives `/proc/PID/mem`,
//! `environ`, `fd` and `ptrace` to root only, even where Yama is absent. Only the process itself
//! can set it, since `execve` resets it: `armor run` cannot do it for the module.
#![allow(unsafe_code)]

use std::io::{self, Read as _};
use std::os::fd::{FromRawFd as _, OwnedFd};

/// Makes this process non-dumpable (see the module's comment); logs why not if it cannot.
pub fn make_non_dumpable() {
    // SAFETY: PR_SET_DUMPABLE takes one integer argument and touches no memory of ours.
    let done = unsafe { libc::prctl(libc::PR_SET_DUMPABLE, 0, 0, 0, 0) };
    if done != 0 {
        tracing::warn!(
            "cannot make this process non-dumpable: {:#}",
            io::Error::last_os_error()
        );
    }
}

/// Reads descriptor `fd` (a decimal number, from `ARMOR_KEY_FD`) to its end and closes it; the
/// descriptor's number then stands for `/dev/null`, so that nothing opened later takes it
/// over by accident. Called once per process: a second call finds `/dev/null` and reads nothing.
pub fn take_key_fd(fd: &str) -> io::Result<String> {
    let number: i32 = fd
        .trim()
        .parse()
        .ok()
        .filter(|number| *number >= 0)
        .ok_or_else(|| io::Error::new(io::ErrorKind::InvalidInput, "not a descriptor number"))?;
    // SAFETY: F_GETFD only asks whether the number is an open descriptor.
    if unsafe { libc::fcntl(number, libc::F_GETFD) } < 0 {
        return Err(io::Error::last_os_error());
    }
    let null = std::fs::File::open("/dev/null")?;
    // SAFETY: the number is open (checked above) and was handed to this process for its key
    // alone (`ARMOR_KEY_FD`); nothing else in the process owns it.
    let mut file = std::fs::File::from(unsafe { OwnedFd::from_raw_fd(number) });
    let mut text = String::new();
    let read = (&mut file).take(1024).read_to_string(&mut text);
    // The pipe goes, and the number points at /dev/null (dup2 closes the pipe's end).
    // SAFETY: both are open descriptors of this process; `file` is forgotten so that its drop
    // does not close the number dup2 has just reused.
    let duplicated = unsafe { libc::dup2(std::os::fd::AsRawFd::as_raw_fd(&null), number) };
    std::mem::forget(file);
    if duplicated < 0 {
        return Err(io::Error::last_os_error());
    }
    read?;
    Ok(text)
}
