//! The module API's data types: the first byte picks one (Counter, Text, Blob, Pose2D, Twist,
//! Odometry, LaserScan, OccupancyGrid, Image, Markers), the rest is decoded as a payload from a
//! peer would be. Decoding never panics, never allocates more than four bytes per byte of input
//! (a marker's size in memory per byte for `Markers`) whatever length a sequence announces, and
//! what it accepts encodes to bytes that decode and encode to themselves.
#![no_main]

use armor_fuzz::counting::{Counting, measure};
use armor_module_api::Datum;
use armor_module_api::types::{
    Blob, Counter, Image, LaserScan, Marker, Markers, OccupancyGrid, Odometry, Pose2D, Text, Twist,
};
use libfuzzer_sys::fuzz_target;

#[global_allocator]
static ALLOCATOR: Counting = Counting;

fn check<T: Datum>(bytes: &[u8]) {
    check_within::<T>(bytes, 4);
}

/// `per_byte`: the most bytes decoding may allocate at once per byte of input.
fn check_within<T: Datum>(bytes: &[u8], per_byte: usize) {
    let (decoded, largest) = measure(|| T::decode(bytes));
    // Postcard hints a sequence's length to serde only when at least that many bytes are left
    // (elements against bytes), and serde preallocates what it is hinted, up to 1 MiB: the
    // largest element in memory, an f32, takes four bytes, so at most four bytes per byte of
    // input. Without a hint, a vector grows by doubling to what the bytes hold. A sequence of
    // markers is hinted as many elements as bytes left, each a `Marker` in memory.
    let bound = per_byte * bytes.len() + 64;
    assert!(
        largest <= bound,
        "decoding {} bytes as {} allocated {largest} bytes at once",
        bytes.len(),
        T::TYPE
    );
    let (owned, _) = measure(|| T::decode_owned(bytes.to_vec()));
    assert_eq!(
        decoded.is_ok(),
        owned.is_ok(),
        "decode and decode_owned disagree"
    );
    let Ok(value) = decoded else {
        return;
    };
    // Compared as bytes, not values: NaN is not equal to itself, and an overlong varint is
    // accepted but written short.
    let mut encoded = Vec::new();
    value.encode(&mut encoded).expect("a decoded value encodes");
    let again = T::decode(&encoded)
        .unwrap_or_else(|err| panic!("own encoding refused: {err}\n{encoded:?}"));
    let mut encoded_again = Vec::new();
    again.encode(&mut encoded_again).expect("encodes");
    assert_eq!(
        encoded,
        encoded_again,
        "the encoding of {} is not stable",
        T::TYPE
    );
}

fuzz_target!(|data: &[u8]| {
    let Some((&which, payload)) = data.split_first() else {
        return;
    };
    match which % 10 {
        0 => check::<Counter>(payload),
        1 => check::<Text>(payload),
        2 => check::<Blob>(payload),
        3 => check::<Pose2D>(payload),
        4 => check::<Twist>(payload),
        5 => check::<Odometry>(payload),
        6 => check::<LaserScan>(payload),
        7 => check::<OccupancyGrid>(payload),
        8 => check::<Image>(payload),
        _ => check_within::<Markers>(payload, std::mem::size_of::<Marker>()),
    }
});
