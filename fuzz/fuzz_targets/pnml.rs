//! PNML: `from_pnml` never panics, and what it accepts survives `to_pnml`.
#![no_main]

use armor_model::net::{from_pnml, to_pnml};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|text: &str| {
    if let Ok(net) = from_pnml(text) {
        let written = to_pnml(&net);
        let again = from_pnml(&written)
            .unwrap_or_else(|problems| panic!("own output refused: {problems:?}\n{written}"));
        armor_fuzz::assert_same(&net, &again, &written);
    }
});
