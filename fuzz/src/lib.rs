//! What the fuzz targets share: comparing parsed values while ignoring where they were read from,
//! an allocator that counts ([`counting`]), and the studio's checks of untrusted data
//! ([`untrusted`], compiled from the studio's own file).

use std::fmt::Debug;

/// The Run view's checks of grids, scans, poses and recording times, from the studio's source:
/// that file uses only `std` and the module API, so the studio's GUI stack need not be built
/// with sanitizers to fuzz it.
#[path = "../../app/src/run/untrusted.rs"]
pub mod untrusted;

/// The `Debug` text of `value` with every `Pos { line: L, col: C }` replaced by `Pos`: two values
/// read from different texts compare equal this way when only their positions differ. (`Debug`
/// rather than `PartialEq`, so that it also sees every field added later, and tells `-0.0` from
/// `0.0`.)
pub fn without_positions(value: &impl Debug) -> String {
    const MARK: &str = "Pos { line: ";
    let text = format!("{value:?}");
    let mut out = String::with_capacity(text.len());
    let mut rest = text.as_str();
    while let Some(at) = rest.find(MARK) {
        out.push_str(&rest[..at]);
        out.push_str("Pos");
        let after = &rest[at + MARK.len()..];
        rest = after.find('}').map_or("", |end| &after[end + 1..]);
    }
    out.push_str(rest);
    out
}

/// Asserts that `again` (read back from what was written from `first`) is `first`, positions aside.
pub fn assert_same<T: Debug>(first: &T, again: &T, written: &str) {
    let (a, b) = (without_positions(first), without_positions(again));
    assert!(
        a == b,
        "round trip changed the value\nfirst: {a}\nagain: {b}\nwritten:\n{written}"
    );
}

/// A global allocator that passes everything to the system's and, while [`counting::measure`]
/// runs, records the largest single allocation. A target installs it with
/// `#[global_allocator] static ALLOCATOR: armor_fuzz::counting::Counting = armor_fuzz::counting::Counting;`.
pub mod counting {
    use std::alloc::{GlobalAlloc, Layout, System};
    use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering::Relaxed};

    pub struct Counting;

    static COUNTING: AtomicBool = AtomicBool::new(false);
    static LARGEST: AtomicUsize = AtomicUsize::new(0);

    fn on_alloc(size: usize) {
        if COUNTING.load(Relaxed) {
            LARGEST.fetch_max(size, Relaxed);
        }
    }

    // SAFETY: every call is passed to the system allocator unchanged; only sizes are counted.
    #[allow(unsafe_code)]
    unsafe impl GlobalAlloc for Counting {
        unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
            on_alloc(layout.size());
            unsafe { System.alloc(layout) }
        }
        unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
            on_alloc(layout.size());
            unsafe { System.alloc_zeroed(layout) }
        }
        unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
            unsafe { System.dealloc(ptr, layout) }
        }
        unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
            on_alloc(new_size);
            unsafe { System.realloc(ptr, layout, new_size) }
        }
    }

    /// Runs `f`, and returns what it returned with the largest single allocation it made (in
    /// bytes; 0 unless [`Counting`] is the global allocator).
    pub fn measure<T>(f: impl FnOnce() -> T) -> (T, usize) {
        LARGEST.store(0, Relaxed);
        COUNTING.store(true, Relaxed);
        let value = f();
        COUNTING.store(false, Relaxed);
        (value, LARGEST.load(Relaxed))
    }
}
