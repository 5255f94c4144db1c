//! Mission nets: `MissionNet::parse` never panics, and what it accepts survives `to_xml`.
#![no_main]

use armor_model::net::MissionNet;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|text: &str| {
    if let Ok(net) = MissionNet::parse(text) {
        let written = net.to_xml();
        let again = MissionNet::parse(&written)
            .unwrap_or_else(|problems| panic!("own output refused: {problems:?}\n{written}"));
        armor_fuzz::assert_same(&net, &again, &written);
    }
});
