//! Describe output: `ModuleDescription::from_xml` never panics, and what it accepts survives
//! `to_xml`.
#![no_main]

use armor_module_api::describe::ModuleDescription;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|text: &str| {
    if let Ok(description) = ModuleDescription::from_xml(text) {
        let written = description.to_xml();
        let again = ModuleDescription::from_xml(&written)
            .unwrap_or_else(|problems| panic!("own output refused: {problems:?}\n{written}"));
        armor_fuzz::assert_same(&description, &again, &written);
    }
});
