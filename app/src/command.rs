//! Every command of the studio's menus and keys in one table, as rerun's `UICommand`: its label
//! in each view's menus, its keys, its line in the keyboard sheet (F1) and the views whose keys
//! run it. The menus ([`menus`]), the key handling ([`triggered`]) and the sheet ([`help_ui`])
//! all read the table, so a key shown can never disagree with the key that works. What a
//! command does depends on the view shown; the window (`app.rs`) routes it there.

use egui::{Key, KeyboardShortcut, ModifierNames, Modifiers, RichText};

/// The studio's views: the system's block diagram, the mission's map, the run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum View {
    System,
    Mission,
    Run,
}

/// The studio's commands, in the order the keyboard sheet lists them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum UiCommand {
    Save,
    SaveAs,
    Open,
    Undo,
    Redo,
    Cut,
    Copy,
    Paste,
    Duplicate,
    SelectAll,
    Delete,
    ClearSelection,
    Group,
    Ungroup,
    Up,
    ZoomToFit,
    Find,
    Help,
    Run,
    Stop,
    Attach,
    New,
    ExportPng,
    Arrange,
    ImportGpx,
    ExportMission,
    ExportPnml,
    BaseMap,
    Quit,
}

const CTRL: Modifiers = Modifiers::COMMAND;
const CTRL_SHIFT: Modifiers = Modifiers::COMMAND.plus(Modifiers::SHIFT);

const fn key(modifiers: Modifiers, key: Key) -> KeyboardShortcut {
    KeyboardShortcut::new(modifiers, key)
}

impl UiCommand {
    pub const ALL: [UiCommand; 29] = [
        UiCommand::Save,
        UiCommand::SaveAs,
        UiCommand::Open,
        UiCommand::Undo,
        UiCommand::Redo,
        UiCommand::Cut,
        UiCommand::Copy,
        UiCommand::Paste,
        UiCommand::Duplicate,
        UiCommand::SelectAll,
        UiCommand::Delete,
        UiCommand::ClearSelection,
        UiCommand::Group,
        UiCommand::Ungroup,
        UiCommand::Up,
        UiCommand::ZoomToFit,
        UiCommand::Find,
        UiCommand::Help,
        UiCommand::Run,
        UiCommand::Stop,
        UiCommand::Attach,
        UiCommand::New,
        UiCommand::ExportPng,
        UiCommand::Arrange,
        UiCommand::ImportGpx,
        UiCommand::ExportMission,
        UiCommand::ExportPnml,
        UiCommand::BaseMap,
        UiCommand::Quit,
    ];

    /// Its label in `view`'s menus.
    pub fn label(self, view: View) -> &'static str {
        let mission = view == View::Mission;
        match self {
            UiCommand::Save if mission => "Save plan",
            UiCommand::Save => "Save",
            UiCommand::SaveAs if mission => "Save plan as…",
            UiCommand::SaveAs => "Save as…",
            UiCommand::Open if mission => "Open plan…",
            UiCommand::Open if view == View::Run => "Open recording…",
            UiCommand::Open => "Open…",
            UiCommand::New if mission => "New plan",
            UiCommand::New => "New",
            UiCommand::ExportPng if mission => "Export map PNG…",
            UiCommand::ExportPng => "Export PNG…",
            UiCommand::Arrange => "Arrange",
            UiCommand::ImportGpx => "Import GPX…",
            UiCommand::ExportMission => "Export mission XML…",
            UiCommand::ExportPnml => "Export PNML…",
            UiCommand::BaseMap => "Base map…",
            UiCommand::Quit => "Quit",
            UiCommand::Undo => "Undo",
            UiCommand::Redo => "Redo",
            UiCommand::Cut => "Cut",
            UiCommand::Copy => "Copy",
            UiCommand::Paste => "Paste",
            UiCommand::Duplicate => "Duplicate",
            UiCommand::SelectAll => "Select all",
            UiCommand::Delete => "Delete",
            UiCommand::ClearSelection => "Clear the selection",
            UiCommand::Group => "Group",
            UiCommand::Ungroup => "Ungroup",
            UiCommand::Up => "Up a level",
            UiCommand::ZoomToFit => "Zoom to fit",
            UiCommand::Find => "Find block…",
            UiCommand::Help => "Keyboard shortcuts",
            UiCommand::Run if mission => "Run plan…",
            UiCommand::Run if view == View::System => "Run system…",
            UiCommand::Run => "Run…",
            UiCommand::Stop => "Stop",
            UiCommand::Attach => "Attach…",
        }
    }

    /// Its keys, in the order the sheet shows them.
    pub fn shortcuts(self) -> &'static [KeyboardShortcut] {
        match self {
            UiCommand::Save => const { &[key(CTRL, Key::S)] },
            UiCommand::SaveAs => const { &[key(CTRL_SHIFT, Key::S)] },
            UiCommand::Open => const { &[key(CTRL, Key::O)] },
            UiCommand::Undo => const { &[key(CTRL, Key::Z)] },
            UiCommand::Redo => const { &[key(CTRL, Key::Y), key(CTRL_SHIFT, Key::Z)] },
            UiCommand::Cut => const { &[key(CTRL, Key::X)] },
            UiCommand::Copy => const { &[key(CTRL, Key::C)] },
            UiCommand::Paste => const { &[key(CTRL, Key::V)] },
            UiCommand::Duplicate => const { &[key(CTRL, Key::D)] },
            UiCommand::SelectAll => const { &[key(CTRL, Key::A)] },
            UiCommand::Delete => {
                const {
                    &[
                        key(Modifiers::NONE, Key::Delete),
                        key(Modifiers::NONE, Key::Backspace),
                    ]
                }
            }
            UiCommand::ClearSelection => const { &[key(Modifiers::NONE, Key::Escape)] },
            UiCommand::Group => const { &[key(CTRL, Key::G)] },
            UiCommand::Ungroup => const { &[key(CTRL_SHIFT, Key::G)] },
            UiCommand::Up => const { &[key(Modifiers::ALT, Key::ArrowUp)] },
            UiCommand::ZoomToFit => {
                const { &[key(Modifiers::NONE, Key::Home), key(CTRL, Key::Num0)] }
            }
            UiCommand::Find => const { &[key(CTRL, Key::F)] },
            UiCommand::Help => const { &[key(Modifiers::NONE, Key::F1)] },
            UiCommand::Run => const { &[key(Modifiers::NONE, Key::F5)] },
            UiCommand::Stop => const { &[key(Modifiers::SHIFT, Key::F5)] },
            UiCommand::New
            | UiCommand::Attach
            | UiCommand::ExportPng
            | UiCommand::Arrange
            | UiCommand::ImportGpx
            | UiCommand::ExportMission
            | UiCommand::ExportPnml
            | UiCommand::BaseMap
            | UiCommand::Quit => const { &[] },
        }
    }

    /// Its keys as the menus and the sheet show them ("Ctrl+Y, Ctrl+Shift+Z"). Written the same
    /// on every platform, as the sheet always has been.
    pub fn keys_text(self) -> String {
        self.shortcuts()
            .iter()
            .map(|shortcut| shortcut.format(&ModifierNames::NAMES, false))
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// What it does, for the keyboard sheet.
    pub fn help(self) -> &'static str {
        match self {
            UiCommand::Save => "save",
            UiCommand::SaveAs => "save as",
            UiCommand::Open => "open a file (type its path)",
            UiCommand::Undo => "undo",
            UiCommand::Redo => "redo",
            UiCommand::Cut => "cut the selected blocks (as system XML on the clipboard)",
            UiCommand::Copy => "copy the selected blocks (as system XML on the clipboard)",
            UiCommand::Paste => "paste blocks (system XML from the clipboard)",
            UiCommand::Duplicate => "duplicate the selected blocks",
            UiCommand::SelectAll => "select all",
            UiCommand::Delete => "delete the selected blocks",
            UiCommand::ClearSelection => "clear the selection",
            UiCommand::Group => {
                "group the selected blocks into a subsystem (double-click it to open it)"
            }
            UiCommand::Ungroup => "put the selected subsystem's blocks back where it is",
            UiCommand::Up => "leave the subsystem shown for the level above",
            UiCommand::ZoomToFit => "zoom to fit",
            UiCommand::Find => "find a block",
            UiCommand::Help => "this sheet",
            UiCommand::Run => {
                "run the document of the view shown (the plan in the Mission view, the system in \
                 the System view; in the Run view, that of the view left), asking the time scale"
            }
            UiCommand::Stop => "stop the run (detach from one attached to)",
            UiCommand::Attach => "watch and operate a run started elsewhere (its control address)",
            UiCommand::New => "a new document",
            UiCommand::ExportPng => "export a picture",
            UiCommand::Arrange => "lay the blocks out by data flow, sources left",
            UiCommand::ImportGpx => "import waypoints and a route (GPX)",
            UiCommand::ExportMission => "export the mission (XML for armor run)",
            UiCommand::ExportPnml => "export the net (PNML)",
            UiCommand::BaseMap => "draw the plan on an offline base map (MBTiles or a tile folder)",
            UiCommand::Quit => "close the window",
        }
    }

    /// Whether its keys run it in `view`.
    pub fn has_keys_in(self, view: View) -> bool {
        match self {
            UiCommand::Run | UiCommand::Stop | UiCommand::Open | UiCommand::Help => true,
            UiCommand::Save
            | UiCommand::SaveAs
            | UiCommand::Undo
            | UiCommand::Redo
            | UiCommand::Delete
            | UiCommand::ClearSelection => view != View::Run,
            UiCommand::ZoomToFit => true,
            UiCommand::Cut
            | UiCommand::Copy
            | UiCommand::Paste
            | UiCommand::Duplicate
            | UiCommand::SelectAll
            | UiCommand::Group
            | UiCommand::Ungroup
            | UiCommand::Up
            | UiCommand::Find => view == View::System,
            UiCommand::New
            | UiCommand::Attach
            | UiCommand::ExportPng
            | UiCommand::Arrange
            | UiCommand::ImportGpx
            | UiCommand::ExportMission
            | UiCommand::ExportPnml
            | UiCommand::BaseMap
            | UiCommand::Quit => false,
        }
    }

    /// Whether its keys work while a text field has the keyboard: the files', the sheet's, the
    /// run's and Find's do; the others would steal the text field's keys.
    pub fn works_while_typing(self) -> bool {
        matches!(
            self,
            UiCommand::Save
                | UiCommand::SaveAs
                | UiCommand::Open
                | UiCommand::Help
                | UiCommand::Find
                | UiCommand::Run
                | UiCommand::Stop
        )
    }

    /// Whether holding its key repeats it, as a text editor's undo and delete do. The others
    /// open, save or start something once per press: a key held down (or a keyboard repeating
    /// while a loaded machine is slow to see it released) must not open a second dialog or start
    /// a second run.
    pub fn repeats_when_held(self) -> bool {
        matches!(
            self,
            UiCommand::Undo | UiCommand::Redo | UiCommand::Delete | UiCommand::Duplicate
        )
    }

    /// Whether its keys come as the platform's clipboard events (the platform turns Ctrl+C,
    /// Ctrl+X and Ctrl+V into copy, cut and paste, the last with the clipboard's text), which
    /// the System view reads itself rather than as shortcuts.
    pub fn is_clipboard(self) -> bool {
        matches!(self, UiCommand::Cut | UiCommand::Copy | UiCommand::Paste)
    }
}

/// The commands whose keys were pressed this frame in `view`, taken from egui's input. While
/// `typing`, only those that work while typing are taken (the others' keys are left alone).
pub fn triggered(ctx: &egui::Context, view: View, typing: bool) -> Vec<UiCommand> {
    let mut candidates: Vec<(UiCommand, Vec<KeyboardShortcut>)> = UiCommand::ALL
        .into_iter()
        .filter(|command| command.has_keys_in(view) && !command.is_clipboard())
        .filter(|command| !typing || command.works_while_typing())
        .map(|command| {
            let mut shortcuts = command.shortcuts().to_vec();
            shortcuts.sort_by_key(|shortcut| std::cmp::Reverse(modifier_count(shortcut)));
            (command, shortcuts)
        })
        .collect();
    // A key held down arrives again as repeats: those of a command that acts once per press
    // are dropped before anything can take them.
    ctx.input_mut(|input| {
        input.events.retain(|event| {
            let egui::Event::Key {
                key,
                modifiers,
                repeat: true,
                ..
            } = event
            else {
                return true;
            };
            !candidates.iter().any(|(command, shortcuts)| {
                !command.repeats_when_held()
                    && shortcuts.iter().any(|shortcut| {
                        shortcut.logical_key == *key
                            && modifiers.matches_logically(shortcut.modifiers)
                    })
            })
        });
    });
    // egui matches keys logically: Ctrl+Z would also take Ctrl+Shift+Z. Keys with more
    // modifiers are therefore tried first (a stable sort keeps the table's order otherwise).
    candidates.sort_by_key(|(_, shortcuts)| {
        std::cmp::Reverse(shortcuts.first().map_or(0, modifier_count))
    });
    candidates
        .into_iter()
        .filter(|(_, shortcuts)| {
            shortcuts
                .iter()
                .any(|shortcut| ctx.input_mut(|input| input.consume_shortcut(shortcut)))
        })
        .map(|(command, _)| command)
        .collect()
}

fn modifier_count(shortcut: &KeyboardShortcut) -> usize {
    let modifiers = shortcut.modifiers;
    [
        modifiers.command || modifiers.ctrl || modifiers.mac_cmd,
        modifiers.shift,
        modifiers.alt,
    ]
    .into_iter()
    .filter(|held| *held)
    .count()
}

/// An entry of a menu.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MenuItem {
    Command(UiCommand),
    Separator,
    /// The submenu of recently opened files.
    Recent,
    /// The submenu of the bundled examples (the start page's list).
    Examples,
    /// A line of text (how the mouse zooms and pans, in the View menu).
    Note(&'static str),
}

/// A menu of the menu bar.
pub struct Menu {
    pub title: &'static str,
    pub items: &'static [MenuItem],
}

use MenuItem::{Command as Item, Examples, Note, Recent, Separator};

/// The View menu's line on the mouse, the same in every view.
const MOUSE_NOTE: MenuItem = Note("Wheel: zoom · drag: pan");

const SYSTEM_MENUS: &[Menu] = &[
    Menu {
        title: "File",
        items: &[
            Item(UiCommand::New),
            Item(UiCommand::Open),
            Recent,
            Examples,
            Item(UiCommand::Save),
            Item(UiCommand::SaveAs),
            Item(UiCommand::ExportPng),
            Item(UiCommand::Arrange),
            Item(UiCommand::Run),
            Item(UiCommand::Quit),
        ],
    },
    Menu {
        title: "Edit",
        items: &[
            Item(UiCommand::Undo),
            Item(UiCommand::Redo),
            Item(UiCommand::Cut),
            Item(UiCommand::Copy),
            Item(UiCommand::Paste),
            Item(UiCommand::Duplicate),
            Item(UiCommand::Delete),
            Item(UiCommand::SelectAll),
            Separator,
            Item(UiCommand::Group),
            Item(UiCommand::Ungroup),
            Item(UiCommand::Up),
        ],
    },
    Menu {
        title: "View",
        items: &[
            Item(UiCommand::ZoomToFit),
            MOUSE_NOTE,
            Separator,
            Item(UiCommand::Find),
            Item(UiCommand::Help),
        ],
    },
];

const MISSION_MENUS: &[Menu] = &[
    Menu {
        title: "File",
        items: &[
            Item(UiCommand::New),
            Item(UiCommand::Open),
            Recent,
            Examples,
            Item(UiCommand::Save),
            Item(UiCommand::SaveAs),
            Separator,
            Item(UiCommand::ImportGpx),
            Item(UiCommand::ExportMission),
            Item(UiCommand::ExportPnml),
            Item(UiCommand::ExportPng),
            Separator,
            Item(UiCommand::Run),
            Item(UiCommand::Quit),
        ],
    },
    Menu {
        title: "Edit",
        items: &[
            Item(UiCommand::Undo),
            Item(UiCommand::Redo),
            Item(UiCommand::Delete),
        ],
    },
    Menu {
        title: "View",
        items: &[
            Item(UiCommand::ZoomToFit),
            Item(UiCommand::BaseMap),
            MOUSE_NOTE,
            Separator,
            Item(UiCommand::Help),
        ],
    },
];

const RUN_MENUS: &[Menu] = &[
    Menu {
        title: "Run",
        items: &[
            Item(UiCommand::Run),
            Item(UiCommand::Stop),
            Item(UiCommand::Attach),
            Separator,
            Item(UiCommand::Open),
        ],
    },
    Menu {
        title: "View",
        items: &[
            Item(UiCommand::ZoomToFit),
            MOUSE_NOTE,
            Separator,
            Item(UiCommand::Help),
        ],
    },
];

/// The menus of `view`, left to right.
pub fn menus(view: View) -> &'static [Menu] {
    match view {
        View::System => SYSTEM_MENUS,
        View::Mission => MISSION_MENUS,
        View::Run => RUN_MENUS,
    }
}

/// What the mouse (and the Run view's arrow keys) do, listed on the sheet after the commands.
pub const GESTURES: &[(&str, &str)] = &[
    ("Wheel", "zoom about the pointer (diagram, map, net)"),
    ("Drag empty space", "pan (diagram, map, net)"),
    ("Double-click a block", "its name and parameters"),
    ("Right-click a block", "parameters, duplicate, delete"),
    ("Right-click the canvas", "add a block"),
    ("Drag from a pin", "link: legal targets turn green"),
    ("Right-click a pin or wire", "remove its links"),
    ("Shift+drag", "select with a rectangle"),
    (
        "Arrow keys (Run view)",
        "drive the robot through teleop while held",
    ),
];

/// The keyboard sheet (F1): every command that has keys, in the table's order, then the
/// gestures.
pub fn help_ui(ctx: &egui::Context, open: &mut bool) {
    egui::Window::new("Keyboard shortcuts")
        .id(egui::Id::new("help"))
        .open(open)
        .collapsible(false)
        .show(ctx, |ui| {
            egui::Grid::new("shortcuts").striped(true).show(ui, |ui| {
                for command in UiCommand::ALL {
                    if command.shortcuts().is_empty() {
                        continue;
                    }
                    ui.label(RichText::new(command.keys_text()).monospace());
                    ui.label(command.help());
                    ui.end_row();
                }
                for (keys, what) in GESTURES {
                    ui.label(RichText::new(*keys).monospace());
                    ui.label(*what);
                    ui.end_row();
                }
            });
        });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_read_as_the_sheet_always_wrote_them() {
        let keys = |command: UiCommand| command.keys_text();
        assert_eq!(keys(UiCommand::Save), "Ctrl+S");
        assert_eq!(keys(UiCommand::SaveAs), "Ctrl+Shift+S");
        assert_eq!(keys(UiCommand::Redo), "Ctrl+Y, Ctrl+Shift+Z");
        assert_eq!(keys(UiCommand::Delete), "Delete, Backspace");
        assert_eq!(keys(UiCommand::ClearSelection), "Escape");
        assert_eq!(keys(UiCommand::ZoomToFit), "Home, Ctrl+0");
        assert_eq!(keys(UiCommand::Run), "F5");
        assert_eq!(keys(UiCommand::Stop), "Shift+F5");
    }

    #[test]
    fn no_two_commands_share_a_key_in_a_view() {
        for view in [View::System, View::Mission, View::Run] {
            let mut seen = Vec::new();
            for command in UiCommand::ALL.into_iter().filter(|c| c.has_keys_in(view)) {
                for shortcut in command.shortcuts() {
                    assert!(
                        !seen.contains(shortcut),
                        "{view:?}: {command:?} reuses {shortcut:?}"
                    );
                    seen.push(*shortcut);
                }
            }
        }
    }

    /// The menus as they were written by hand before the table made them.
    #[test]
    fn menus_read_as_they_always_have() {
        let labels = |view: View| -> Vec<(&str, Vec<&str>)> {
            menus(view)
                .iter()
                .map(|menu| {
                    let items = menu.items.iter().map(|item| match item {
                        MenuItem::Command(command) => command.label(view),
                        MenuItem::Separator => "---",
                        MenuItem::Recent => "Open recent",
                        MenuItem::Examples => "Examples",
                        MenuItem::Note(text) => text,
                    });
                    (menu.title, items.collect())
                })
                .collect()
        };
        let system_file = [
            "New",
            "Open…",
            "Open recent",
            "Examples",
            "Save",
            "Save as…",
            "Export PNG…",
            "Arrange",
            "Run system…",
            "Quit",
        ];
        let system_edit = [
            "Undo",
            "Redo",
            "Cut",
            "Copy",
            "Paste",
            "Duplicate",
            "Delete",
            "Select all",
            "---",
            "Group",
            "Ungroup",
            "Up a level",
        ];
        let mission_file = [
            "New plan",
            "Open plan…",
            "Open recent",
            "Examples",
            "Save plan",
            "Save plan as…",
            "---",
            "Import GPX…",
            "Export mission XML…",
            "Export PNML…",
            "Export map PNG…",
            "---",
            "Run plan…",
            "Quit",
        ];
        assert_eq!(
            labels(View::System),
            [
                ("File", system_file.to_vec()),
                ("Edit", system_edit.to_vec()),
                (
                    "View",
                    vec![
                        "Zoom to fit",
                        "Wheel: zoom · drag: pan",
                        "---",
                        "Find block…",
                        "Keyboard shortcuts"
                    ]
                ),
            ]
        );
        assert_eq!(
            labels(View::Mission),
            [
                ("File", mission_file.to_vec()),
                ("Edit", vec!["Undo", "Redo", "Delete"]),
                (
                    "View",
                    vec![
                        "Zoom to fit",
                        "Base map…",
                        "Wheel: zoom · drag: pan",
                        "---",
                        "Keyboard shortcuts"
                    ]
                ),
            ]
        );
        assert_eq!(
            labels(View::Run),
            [
                (
                    "Run",
                    vec!["Run…", "Stop", "Attach…", "---", "Open recording…"]
                ),
                (
                    "View",
                    vec![
                        "Zoom to fit",
                        "Wheel: zoom · drag: pan",
                        "---",
                        "Keyboard shortcuts"
                    ]
                ),
            ]
        );
        // The View menu is in every view, so that the menu bar does not move.
        for view in [View::System, View::Mission, View::Run] {
            assert!(menus(view).iter().any(|menu| menu.title == "View"));
        }
        let run_keys: Vec<String> = [UiCommand::Run, UiCommand::Stop, UiCommand::Open]
            .into_iter()
            .map(UiCommand::keys_text)
            .collect();
        assert_eq!(run_keys, ["F5", "Shift+F5", "Ctrl+O"]);
    }

    #[test]
    fn every_command_is_in_the_table_once() {
        for command in UiCommand::ALL {
            let count = UiCommand::ALL.iter().filter(|c| **c == command).count();
            assert_eq!(count, 1, "{command:?}");
        }
    }
}
