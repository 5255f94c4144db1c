//! ArMoR Studio: a window with three views, each in its own folder with its own state, which
//! the shell ([`app`]) routes frames, menus and keys to, handing each the same per-frame
//! [`common::context::ViewerContext`]:
//!
//! - [`system`]: the block-diagram editor of a system file. Module binaries on the module path
//!   describe themselves ([`common::palette`]); blocks and links are drawn on a canvas
//!   ([`system::viewer`], an egui-snarl adapter over the [`system::diagram`] model, edited
//!   through the [`system::editor`]'s commands and undo history), checked with the same
//!   function as `armor check` ([`system::validation`]), and saved in the one system XML format
//!   that `armor run` runs ([`files`]).
//! - [`mission`]: a plan on an offline map, compiled and verified as `armor compile` and
//!   `armor check` do, with the net it compiles to.
//! - [`run`](mod@run): a run of the `armor` binary (or one attached to through its control
//!   interface, or a recording) watched and driven live.
//!
//! What two views share lives in [`common`]; a view names another only by the types its room
//! exports at its root (the Run view draws on the Mission view's `MissionView`), never its files
//! (`tests/rooms.rs` fails otherwise). The menus, the keys and the F1 sheet are all made from
//! one table ([`command`]). Start the window with [`run()`] or [`run_attached`]; tests drive
//! [`StudioApp::ui`] in an egui_kittest harness.
//!
//! An operator's station for a team of robots ([`station`], issue 41) opens in a window of its
//! own ([`run_station`]): it shows the team that `armor-team station` reports, not one run.

pub mod app;
pub mod browser;
pub mod command;
pub mod common;
pub mod dialogs;
pub mod export;
pub mod files;
pub mod mission;
pub mod run;
pub mod start;
pub mod station;
pub mod system;

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

/// What a program that draws the studio's frames sets up first (`armor-studio`, and
/// `armor-studio-bench`, so that frames are measured as the window draws them): freed heap kept
/// for the next frame, and logs on stderr (`warn`, or `RUST_LOG`).
pub fn init_process() {
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
    open_window("ArMoR Studio", Box::new(Window(StudioApp::new(options))))
}

/// Opens a 1280×800 window titled `title` drawing `app`, until it is closed.
fn open_window(title: &str, app: Box<dyn eframe::App>) -> anyhow::Result<()> {
    let native = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default()
            .with_title(title)
            .with_inner_size([1280.0, 800.0]),
        ..Default::default()
    };
    eframe::run_native(title, native, Box::new(move |_| Ok(app)))
        .map_err(|err| anyhow::anyhow!("cannot open the window: {err}"))
}

/// Opens an operator's station in a window of its own: `armor-team station ARGS…` started and
/// read ([`station::Link`]), every robot of the team in a table and on one map.
pub fn run_station(args: &[String]) -> anyhow::Result<()> {
    let link = station::Link::spawn(&station::team_program(), args)?;
    open_window(
        "ArMoR Studio: team station",
        Box::new(StationWindow(station::StationView::new(link))),
    )
}

struct StationWindow(station::StationView);

impl eframe::App for StationWindow {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        self.0.ui(ui);
    }
}
