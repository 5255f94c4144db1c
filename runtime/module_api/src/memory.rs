//! The heap policy of a module process.
//!
//! A module that receives large samples allocates a payload buffer per sample and frees it when
//! done (the payload is the module's own value, so it cannot be recycled). glibc gives the top of
//! its heap back to the system as soon as more than about twice the largest recent block lies
//! free there, so a stream of 1 MiB samples grows and shrinks the heap every few samples, and
//! every page of every new buffer is faulted in again: `armor-bench throughput_1mib` counted
//! some 59 page faults per sample in `armor-mod-sink` and a heap resize every two samples.
//! Keeping up to [`TRIM_THRESHOLD_BYTES`] of freed heap lets the next buffer reuse the last
//! one's pages.
#![allow(unsafe_code)]

/// Freed heap kept for reuse before glibc trims it (glibc's own default is 128 KiB, raised
/// as large blocks come and go, up to 64 MiB).
pub const TRIM_THRESHOLD_BYTES: i32 = 64 * 1024 * 1024;
/// Blocks from this size on get their own mapping (glibc's largest allowed value). Setting
/// either parameter turns glibc's own adjustment of both off, so both are set: with the
/// mapping threshold left at its 128 KiB start, every large payload would be mapped and
/// unmapped, which made `throughput_1mib` three times slower.
pub const MMAP_THRESHOLD_BYTES: i32 = 32 * 1024 * 1024;

/// Keeps up to [`TRIM_THRESHOLD_BYTES`] of freed heap in the process (glibc only; elsewhere
/// nothing changes).
pub fn keep_freed_heap() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only sets a parameter of the allocator; it is called once, at start.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES);
        libc::mallopt(libc::M_TRIM_THRESHOLD, TRIM_THRESHOLD_BYTES);
    }
}
