use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use armor_module_catalog::recorder::{body_until, spec};
use signal_hook::consts::{SIGINT, SIGTERM};

fn main() -> std::process::ExitCode {
    // SIGTERM and SIGINT ask the recorder to save its file and exit; a second one kills it.
    let terminate = Arc::new(AtomicBool::new(false));
    for signal in [SIGTERM, SIGINT] {
        let registered =
            signal_hook::flag::register_conditional_shutdown(signal, 1, Arc::clone(&terminate))
                .and_then(|_| signal_hook::flag::register(signal, Arc::clone(&terminate)));
        if let Err(err) = registered {
            eprintln!("warning: cannot handle signal {signal}: {err}");
        }
    }
    armor_module_api::run(spec(), |node| body_until(node, &terminate))
}
