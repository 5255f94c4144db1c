//! Wire frames: arbitrary bytes, cut into arbitrary pieces, fed to `wire::FrameReader`. It must
//! return frames or errors, never panic, and never allocate beyond what the 64 MiB frame cap
//! allows, whatever length a peer announces.
//!
//! Input layout: `flags`, `n`, `n` piece sizes (0: all the rest at once), then the stream.
//! `flags` bit 0: the reader expects a hello; bit 1: it must authenticate (a fixed secret).
#![no_main]

use std::alloc::{GlobalAlloc, Layout, System};
use std::io::{self, Read};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering::Relaxed};

use armor_module_api::auth::{Admit, Dial, Listen, Secret};
use armor_module_api::wire::{Frame, FrameReader, MAX_FRAME_BYTES};
use libfuzzer_sys::fuzz_target;

/// Counts what is allocated while `COUNTING` is set: the largest single allocation and the peak
/// of live bytes.
struct Counting;

static COUNTING: AtomicBool = AtomicBool::new(false);
static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);
static LARGEST: AtomicUsize = AtomicUsize::new(0);

fn on_alloc(size: usize) {
    if COUNTING.load(Relaxed) {
        let live = LIVE.fetch_add(size, Relaxed) + size;
        PEAK.fetch_max(live, Relaxed);
        LARGEST.fetch_max(size, Relaxed);
    }
}

fn on_free(size: usize) {
    if COUNTING.load(Relaxed) {
        // Saturating: a block allocated before counting started may be freed during it.
        let _ = LIVE.fetch_update(Relaxed, Relaxed, |live| Some(live.saturating_sub(size)));
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
        on_free(layout.size());
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // While moving, both blocks are live.
        on_alloc(new_size);
        let moved = unsafe { System.realloc(ptr, layout, new_size) };
        on_free(layout.size());
        moved
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// Hands out the stream in the pieces the input asks for, cycling through their sizes.
struct Pieces<'a> {
    bytes: &'a [u8],
    sizes: &'a [u8],
    next: usize,
}

impl Read for Pieces<'_> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let size = match self.sizes.get(self.next % self.sizes.len().max(1)) {
            None | Some(0) => usize::MAX,
            Some(&size) => usize::from(size),
        };
        self.next += 1;
        let n = size.min(self.bytes.len()).min(buf.len());
        buf[..n].copy_from_slice(&self.bytes[..n]);
        self.bytes = &self.bytes[n..];
        Ok(n)
    }
}

fn run(mut reader: FrameReader, source: &mut Pieces<'_>) {
    let check = |frame: &Frame| {
        if let Frame::Data(data) = frame {
            assert!(data.payload.len() <= MAX_FRAME_BYTES);
        }
        if let Frame::Message(json) = frame {
            assert!(json.len() <= MAX_FRAME_BYTES);
        }
    };
    match reader.next_frame() {
        Ok(Some(frame)) => panic!("a frame out of nothing: {frame:?}"),
        Ok(None) => {}
        Err(_) => return,
    }
    // Every read gives at least one byte until the stream ends, so this ends.
    loop {
        let got = reader
            .fill_from(source)
            .expect("reading a slice never fails");
        loop {
            match reader.next_frame() {
                Ok(Some(frame)) => check(&frame),
                Ok(None) => break,
                Err(_) => return,
            }
        }
        if got == 0 {
            return;
        }
    }
}

fuzz_target!(|data: &[u8]| {
    let Some((&flags, rest)) = data.split_first() else {
        return;
    };
    let Some((&count, rest)) = rest.split_first() else {
        return;
    };
    let count = usize::from(count % 16).min(rest.len());
    let (sizes, bytes) = rest.split_at(count);
    let secret = Secret::from_bytes(b"fuzz secret");
    // With a handshake (as listener or dialer) the fuzzer, which holds no key, never gets
    // past it: what it can make the reader hold is bounded by a handshake frame.
    let authenticating = flags & 6 != 0;
    let reader = if flags & 2 != 0 {
        FrameReader::listener(Some(Listen {
            admit: Admit::Modules(secret),
            encrypt: flags & 8 != 0,
        }))
    } else if flags & 4 != 0 {
        let dial = Dial {
            key: secret.module_key("fuzz"),
            identity: "fuzz".into(),
            encrypt: flags & 8 != 0,
        };
        FrameReader::dialer(Some(&dial)).expect("a valid identity").0
    } else if flags & 1 != 0 {
        FrameReader::expecting_hello()
    } else {
        FrameReader::default()
    };
    let mut source = Pieces {
        bytes,
        sizes,
        next: 0,
    };
    LIVE.store(0, Relaxed);
    PEAK.store(0, Relaxed);
    LARGEST.store(0, Relaxed);
    COUNTING.store(true, Relaxed);
    run(reader, &mut source);
    COUNTING.store(false, Relaxed);
    let (largest, peak) = (LARGEST.load(Relaxed), PEAK.load(Relaxed));
    assert!(
        largest <= MAX_FRAME_BYTES,
        "one allocation of {largest} bytes, beyond the {MAX_FRAME_BYTES}-byte frame cap"
    );
    assert!(
        !authenticating || peak <= 64 * 1024,
        "{peak} bytes live at once for a peer that has not authenticated"
    );
    assert!(
        peak <= 2 * MAX_FRAME_BYTES,
        "{peak} bytes live at once, beyond twice the {MAX_FRAME_BYTES}-byte frame cap"
    );
});
