//! `armor-studio-bench [NAME…] [--quick]`, or `armor-studio-bench monitor CONTROL SYSTEM SECS`:
//! the studio's timings as JSON lines, which `armor-bench` runs and relays.

use std::process::ExitCode;

fn main() -> ExitCode {
    armor_studio::init_process();
    let args: Vec<String> = std::env::args().skip(1).collect();
    match armor_studio_bench::run(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("armor-studio-bench: {err:#}");
            ExitCode::FAILURE
        }
    }
}
