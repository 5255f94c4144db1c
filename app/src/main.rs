//! `armor-studio [FILE]`: ArMoR Studio — the System view (a block-diagram editor), the Mission
//! view (plans on a map) and the Run view. Its timings are `armor-studio-bench`'s
//! (`bench/studio`).

use std::path::PathBuf;
use std::process::ExitCode;

fn main() -> ExitCode {
    armor_studio::init_process();
    let args: Vec<String> = std::env::args().skip(1).collect();
    let result = match args.first().map(String::as_str) {
        Some("--help" | "-h") => {
            println!(
                "usage: armor-studio [FILE]\n       armor-studio --attach ADDR [FILE]\n       armor-studio --station --key KEY --robot NAME… --connect ENDPOINT…\n\nOpens ArMoR Studio: the System view (the block diagram of a robot's modules), the\nMission view (a plan on a map, compiled to a Petri net) and the Run view (a run watched\nand driven live). FILE, if given, is a system file (System view) or a plan (Mission view).\nWith --attach, the Run view follows the run whose control interface is at ADDR (as\n`armor run` prints it), started elsewhere: the same controls as armor ctl; detaching\nleaves it going. Its system FILE, if given, feeds the live map. With --station, an\noperator's station for a team of robots (`armor-team station`'s arguments, docs/team.md):\nevery robot in a table and on one map, and commands sent to one or all."
            );
            Ok(())
        }
        Some("--station") => armor_studio::run_station(&args[1..]),
        Some("--attach") => match (args.get(1), args.get(2), args.len()) {
            (Some(addr), file, 2 | 3) => match addr.parse::<std::net::SocketAddr>() {
                Ok(addr) => armor_studio::run_attached(file.map(PathBuf::from), Some(addr)),
                Err(_) => Err(anyhow::anyhow!(
                    "--attach `{addr}`: expected the run's control address, IP:PORT"
                )),
            },
            _ => Err(anyhow::anyhow!("usage: armor-studio --attach ADDR [FILE]")),
        },
        Some(file) if args.len() == 1 => armor_studio::run(Some(PathBuf::from(file))),
        None => armor_studio::run(None),
        Some(_) => Err(anyhow::anyhow!(
            "usage: armor-studio [FILE] or armor-studio --attach ADDR [FILE]"
        )),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("armor-studio: {err:#}");
            ExitCode::FAILURE
        }
    }
}
