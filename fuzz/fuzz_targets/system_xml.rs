//! System files: `SystemConfig::parse` never panics, and what it accepts survives `to_xml`.
#![no_main]

use armor_model::system::SystemConfig;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|text: &str| {
    if let Ok(config) = SystemConfig::parse(text) {
        let written = config.to_xml();
        let again = SystemConfig::parse(&written)
            .unwrap_or_else(|problems| panic!("own output refused: {problems:?}\n{written}"));
        armor_fuzz::assert_same(&config, &again, &written);
    }
});
