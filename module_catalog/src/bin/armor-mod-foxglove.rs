use armor_module_catalog::foxglove_bridge::{body, spec};

fn main() -> std::process::ExitCode {
    armor_module_api::run(spec(), body)
}
