use armor_module_catalog::localiser::{body, spec};

fn main() -> std::process::ExitCode {
    armor_module_api::run(spec(), body)
}
