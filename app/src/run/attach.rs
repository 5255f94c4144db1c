//! Run → Attach…: the small window that asks for the control address of a run started
//! elsewhere (`armor run` prints it: `armor run control interface at ADDR`), which the Run view
//! then follows with the same controls as `armor ctl`. Detaching (the Stop button, Shift+F5)
//! leaves the run going. A run attached without its system file sends its files
//! ([`armor_protocol::Request::Files`]), which [`mirror`] writes into a folder of their
//! own for the live map.

use std::net::SocketAddr;
use std::path::{Component, Path, PathBuf};

use armor_model::SystemConfig;
use armor_protocol::RunFiles;

/// The prompt's state: the address typed so far, and why the last one was refused.
#[derive(Clone, Debug, Default)]
pub struct AttachPrompt {
    pub addr: String,
    pub error: Option<String>,
}

/// What the prompt asks of the window this frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Answer {
    Attach(SocketAddr),
    Cancel,
}

impl AttachPrompt {
    pub fn new(addr: &str) -> AttachPrompt {
        AttachPrompt {
            addr: addr.to_owned(),
            error: None,
        }
    }

    /// Draws the prompt; returns the operator's answer once given.
    pub fn ui(&mut self, ctx: &egui::Context) -> Option<Answer> {
        let mut answer = None;
        egui::Window::new("Attach to a run")
            .collapsible(false)
            .resizable(false)
            .anchor(egui::Align2::CENTER_CENTER, [0.0, 0.0])
            .show(ctx, |ui| {
                ui.label("The run's control address, as armor run prints it:");
                let field = ui.add(
                    egui::TextEdit::singleline(&mut self.addr)
                        .desired_width(260.0)
                        .hint_text("10.0.0.2:7420"),
                );
                // Any Enter while the prompt is open answers it: the field gives up its focus on
                // Enter, and a field that never had it (a window without a focused widget yet,
                // the prompt just opened from the menu) would otherwise drop the key.
                let enter = ui.input(|input| input.key_pressed(egui::Key::Enter));
                if !enter {
                    field.request_focus();
                }
                if let Some(error) = &self.error {
                    ui.colored_label(ui.visuals().error_fg_color, error);
                }
                ui.horizontal(|ui| {
                    if ui.button("Attach").clicked() || enter {
                        match self.addr.trim().parse::<SocketAddr>() {
                            Ok(addr) => answer = Some(Answer::Attach(addr)),
                            Err(_) => {
                                self.error = Some(format!(
                                    "`{}` is not an address (IP:PORT)",
                                    self.addr.trim()
                                ));
                            }
                        }
                    }
                    if ui.button("Cancel").clicked()
                        || ui.input(|input| input.key_pressed(egui::Key::Escape))
                    {
                        answer = Some(Answer::Cancel);
                    }
                });
            });
        answer
    }
}

/// The files of a run attached without them ([`armor_protocol::RunFiles`]), written
/// into a folder of their own as the run's machine has them side by side, so that the Run view
/// draws the run as if its system file had been opened: the system file, the files its
/// parameters name (the simulated world) where it names them, the mission; and the catalog of
/// the run's own module descriptions, for the live views' sources even where the studio's
/// machine has no module binaries. The folder goes when this does.
pub struct Mirror {
    folder: tempfile::TempDir,
    /// The system file's copy.
    pub system: PathBuf,
    /// The mission's copy, when the run has one.
    pub mission: Option<PathBuf>,
    pub catalog: crate::common::palette::Catalog,
}

impl Mirror {
    /// Whether `path` is one of these copies: a document the studio did not open, which a Run
    /// must not offer to start once detached.
    pub fn holds(&self, path: &Path) -> bool {
        path.starts_with(self.folder.path())
    }
}

/// The last part of a path written on another machine (`/robot/missions/system.xml`), or
/// `fallback`.
fn file_name(path: &str, fallback: &str) -> String {
    Path::new(path)
        .file_name()
        .and_then(|name| name.to_str())
        .filter(|name| !name.is_empty())
        .unwrap_or(fallback)
        .to_owned()
}

/// Where the system and the mission go in the folder: as they lie on the run's machine below
/// the folder both are in, so that the mission names its system as it does there; a file alone
/// goes at the top.
fn layout(system: &str, mission: Option<&str>) -> (PathBuf, Option<PathBuf>) {
    let alone = |path: &str, fallback: &str| PathBuf::from(file_name(path, fallback));
    let Some(mission) = mission else {
        return (alone(system, "system.xml"), None);
    };
    // `plans/../robot/system.xml` is `robot/system.xml`: the run names a plan's system from
    // the plan's folder.
    let lexical = |path: &str| {
        let mut clean = PathBuf::new();
        for part in Path::new(path).components() {
            match part {
                Component::ParentDir
                    if matches!(clean.components().next_back(), Some(Component::Normal(_))) =>
                {
                    clean.pop();
                }
                Component::CurDir => {}
                part => clean.push(part),
            }
        }
        clean
    };
    let (system_path, mission_path) = (&lexical(system), &lexical(mission));
    let common: PathBuf = system_path
        .parent()
        .into_iter()
        .flat_map(Path::components)
        .zip(mission_path.parent().into_iter().flat_map(Path::components))
        .take_while(|(a, b)| a == b)
        .map(|(a, _)| a)
        .collect();
    let below = |path: &Path| {
        path.strip_prefix(&common)
            .ok()
            .filter(|rest| {
                rest.components()
                    .all(|part| matches!(part, Component::Normal(_)))
            })
            .map(Path::to_path_buf)
    };
    match (below(system_path), below(mission_path)) {
        (Some(system), Some(mission)) if system != mission => (system, Some(mission)),
        _ => (
            alone(system, "system.xml"),
            Some(alone(mission, "mission.xml")),
        ),
    }
}

/// Writes the run's files into a new folder (see [`Mirror`]).
pub fn mirror(files: &RunFiles) -> anyhow::Result<Mirror> {
    use anyhow::Context as _;
    let folder = tempfile::Builder::new()
        .prefix("armor-studio-attached-")
        .tempdir()
        .context("cannot make a folder for the run's files")?;
    let system = SystemConfig::parse(&files.system.text).map_err(|problems| {
        anyhow::anyhow!(
            "the run's system file {} does not read here: {}",
            files.system.path,
            problems
                .first()
                .map_or_else(String::new, ToString::to_string)
        )
    })?;
    let mut system_text = files.system.text.clone();
    let (system_at, mission_at) = layout(
        &files.system.path,
        files.mission.as_ref().map(|mission| mission.path.as_str()),
    );
    let system_folder = system_at
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_default();
    let write = |relative: &Path, text: &[u8]| -> anyhow::Result<()> {
        let path = folder.path().join(relative);
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent)?;
        }
        std::fs::write(&path, text).with_context(|| format!("cannot write {}", path.display()))
    };
    for param_file in &files.params {
        let Some(value) = system
            .module(&param_file.module)
            .and_then(|module| {
                module
                    .params
                    .iter()
                    .find(|param| param.name == param_file.param)
            })
            .map(|param| param.value.trim().to_owned())
        else {
            continue;
        };
        // A name below the system's folder is kept as it is written; any other (absolute, or
        // going up) is given a name of its own in the folder, and the system's copy names that.
        let as_written = Path::new(&value);
        let below = as_written
            .components()
            .all(|part| matches!(part, Component::Normal(_)));
        let relative = if below {
            system_folder.join(as_written)
        } else {
            let own = format!(
                "{}-{}-{}",
                param_file.module,
                param_file.param,
                file_name(&param_file.file.path, "file")
            );
            for quote in ['"', '\''] {
                system_text = system_text.replace(
                    &format!("{quote}{value}{quote}"),
                    &format!("{quote}{own}{quote}"),
                );
            }
            system_folder.join(own)
        };
        write(&relative, param_file.file.text.as_bytes())?;
        for beside in &param_file.beside {
            use base64::Engine as _;
            let name = Path::new(&beside.name);
            let Some(folder) = relative.parent() else {
                continue;
            };
            if !name
                .components()
                .all(|part| matches!(part, Component::Normal(_)))
            {
                continue;
            }
            let Ok(bytes) = base64::engine::general_purpose::STANDARD.decode(&beside.base64) else {
                continue;
            };
            write(&folder.join(name), &bytes)?;
        }
    }
    write(&system_at, system_text.as_bytes())?;
    let mission = match (&files.mission, mission_at) {
        (Some(mission), Some(at)) => {
            write(&at, mission.text.as_bytes())?;
            Some(folder.path().join(at))
        }
        _ => None,
    };
    let mut catalog = crate::common::palette::Catalog::new();
    for text in &files.descriptions {
        if let Ok(description) = armor_module_api::ModuleDescription::from_xml(text) {
            catalog.insert(description.module_type.clone(), description);
        }
    }
    Ok(Mirror {
        system: folder.path().join(system_at),
        mission,
        catalog,
        folder,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use armor_protocol::{BinaryFile, FileText, ParamFile};

    #[test]
    fn the_runs_files_are_written_where_the_system_names_them() {
        let files = RunFiles {
            system: FileText {
                path: "/robot/missions/robot.xml".to_owned(),
                text: r#"<system name="r">
  <module name="sim" type="sim"><param name="world" value="worlds/yard.world"/></module>
  <module name="other" type="sim"><param name="world" value="/srv/far.world"/></module>
</system>"#
                    .to_owned(),
            },
            mission: None,
            params: vec![
                ParamFile {
                    module: "sim".to_owned(),
                    param: "world".to_owned(),
                    file: FileText {
                        path: "/robot/missions/worlds/yard.world".to_owned(),
                        text: "yard".to_owned(),
                    },
                    beside: vec![BinaryFile {
                        name: "yard.pgm".to_owned(),
                        base64: "UDUK/w==".to_owned(),
                    }],
                },
                ParamFile {
                    module: "other".to_owned(),
                    param: "world".to_owned(),
                    file: FileText {
                        path: "/srv/far.world".to_owned(),
                        text: "far".to_owned(),
                    },
                    beside: Vec::new(),
                },
            ],
            descriptions: Vec::new(),
        };
        let mirror = mirror(&files).expect("mirror");
        let folder = mirror.system.parent().expect("folder").to_path_buf();
        assert_eq!(mirror.system, folder.join("robot.xml"));
        let read = |name: &str| std::fs::read_to_string(folder.join(name)).expect(name);
        assert_eq!(read("worlds/yard.world"), "yard");
        assert_eq!(read("other-world-far.world"), "far");
        assert_eq!(
            std::fs::read(folder.join("worlds/yard.pgm")).expect("image"),
            b"P5\n\xff",
            "a map's image beside it, byte for byte"
        );
        let system = read("robot.xml");
        assert!(system.contains(r#"value="worlds/yard.world""#), "{system}");
        assert!(
            system.contains(r#"value="other-world-far.world""#),
            "{system}"
        );
        drop(mirror);
        assert!(!folder.exists(), "the folder goes with the mirror");
    }

    #[test]
    fn a_mission_and_its_system_keep_their_places_one_to_the_other() {
        let check = |system: &str, mission: Option<&str>, expected: (&str, Option<&str>)| {
            let (system_at, mission_at) = layout(system, mission);
            assert_eq!(
                (system_at, mission_at),
                (PathBuf::from(expected.0), expected.1.map(PathBuf::from)),
                "{system} {mission:?}"
            );
        };
        check("/m/robot/system.xml", None, ("system.xml", None));
        check(
            "/m/robot/system.xml",
            Some("/m/robot/yard.xml"),
            ("system.xml", Some("yard.xml")),
        );
        check(
            "/m/systems/robot.xml",
            Some("/m/plans/yard.xml"),
            ("systems/robot.xml", Some("plans/yard.xml")),
        );
        check(
            "/m/plans/../systems/robot.xml",
            Some("/m/plans/yard.xml"),
            ("systems/robot.xml", Some("plans/yard.xml")),
        );
        check(
            "relative.xml",
            Some("/m/plan.xml"),
            ("relative.xml", Some("plan.xml")),
        );
    }
}
