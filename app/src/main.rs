//! `armor-studio [FILE]`: ArMoR Studio — the System view (a block-diagram editor), the Mission
//! view (plans on a map) and the Run view. `armor-studio bench` (hidden) prints the studio's
//! timings as JSON lines for `armor-bench`.

use std::path::PathBuf;
use std::process::ExitCode;

fn main() -> ExitCode {
    // A frame's shapes and meshes are large and freed at every frame: kept, the next frame
    // reuses their pages rather than faulting them in again (`markers_frame_ms`).
    armor_module_api::memory::keep_freed_heap();
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn")),
        )
        .with_writer(std::io::stderr)
        .init();
    let args: Vec<String> = std::env::args().skip(1).collect();
    let result = match args.first().map(String::as_str) {
        Some("--help" | "-h") => {
            println!(
                "usage: armor-studio [FILE]\n\nOpens ArMoR Studio: the System view (the block diagram of a robot's modules), the\nMission view (a plan on a map, compiled to a Petri net) and the Run view (a run watched\nand driven live). FILE, if given, is a system file (System view) or a plan (Mission view)."
            );
            Ok(())
        }
        Some("bench") => armor_studio::bench::run(&args[1..]),
        Some(file) if args.len() == 1 => armor_studio::run(Some(PathBuf::from(file))),
        None => armor_studio::run(None),
        Some(_) => Err(anyhow::anyhow!("usage: armor-studio [FILE]")),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("armor-studio: {err:#}");
            ExitCode::FAILURE
        }
    }
}
