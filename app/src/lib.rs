//! ArMoR Studio: the block-diagram editor for a robot's functional layer. It finds module
//! binaries on the module path and asks each to describe itself (`palette`), lets the user draw
//! instances and links on a canvas (`viewer`, an egui-snarl adapter over the `diagram` model,
//! edited through the `editor`'s commands and undo history), checks the result with the same
//! function as `armor check` (`validation`), and reads and writes the one system XML format
//! that `armor run` runs (`files`).
//!
//! Start it with [`run`]; tests drive [`StudioApp::ui`] in an egui_kittest harness.

pub mod app;
pub mod bench;
pub mod command;
pub mod diagram;
pub mod dialogs;
pub mod editor;
pub mod export;
pub mod files;
pub mod layout;
pub mod mission;
pub mod palette;
pub mod run;
pub mod start;
pub mod system;
pub mod validation;
pub mod viewer;

pub use app::{Options, StudioApp};

use std::path::PathBuf;

struct Window(StudioApp);

impl eframe::App for Window {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        self.0.ui(ui);
    }

    fn on_exit(&mut self) {
        self.0.on_exit();
    }
}

/// Opens the studio's window, with `file` loaded if given.
pub fn run(file: Option<PathBuf>) -> anyhow::Result<()> {
    run_attached(file, None)
}

/// Opens the studio's window, with `file` loaded if given, its Run view attached to the run
/// whose control interface is at `attach` if given.
pub fn run_attached(
    file: Option<PathBuf>,
    attach: Option<std::net::SocketAddr>,
) -> anyhow::Result<()> {
    let mut options = Options::new(files::Home::new(files::default_home()));
    options.file = file;
    options.attach = attach;
    options.start_page = true;
    let native = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default()
            .with_title("ArMoR Studio")
            .with_inner_size([1280.0, 800.0]),
        ..Default::default()
    };
    eframe::run_native(
        "ArMoR Studio",
        native,
        Box::new(move |_| Ok(Box::new(Window(StudioApp::new(options))))),
    )
    .map_err(|err| anyhow::anyhow!("cannot open the window: {err}"))
}
