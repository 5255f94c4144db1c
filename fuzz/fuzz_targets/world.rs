//! World files: `World::parse` never panics (there is no writer to round-trip through).
#![no_main]

use armor_model::world::World;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|text: &str| {
    let _ = World::parse(text, "fuzz.world");
});
