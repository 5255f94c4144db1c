//! ArMoR Studio: a window with three views, each in its own module with its own state, which
//! the shell ([`app`]) routes frames, menus and keys to:
//!
//! - [`system`]: the block-diagram editor of a system file. Module binaries on the module path
//!   describe themselves ([`palette`]); blocks and links are drawn on a canvas ([`viewer`], an
//!   egui-snarl adapter over the [`diagram`] model, edited through the [`editor`]'s commands and
//!   undo history), checked with the same function as `armor check` ([`validation`]), and
//!   saved in the one system XML format that `armor run` runs ([`files`]).
//! - [`mission`]: a plan on an offline map, compiled and verified as `armor compile` and
//!   `armor check` do, with the net it compiles to.
//! - [`run`](mod@run): a run of the `armor` binary (or one attached to through its control
//!   interface, or a recording) watched and driven live.
//!
//! The menus, the keys and the F1 sheet are all made from one table ([`command`]). Start the
//! window with [`run()`] or [`run_attached`]; tests drive [`StudioApp::ui`] in an egui_kittest
//! harness.

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
