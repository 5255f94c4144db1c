//! The palette: the module types found on the module path, learnt by running each binary in
//! describe mode on background threads, so that a slow or broken binary never freezes the
//! window. A binary that fails to describe itself stays in the list as an error entry.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::mpsc::{Receiver, TryRecvError, channel};
use std::time::Duration;

use armor_module_api::ModuleDescription;
use armor_runtime::probe;

/// The module descriptions the studio knows, keyed by module type.
pub type Catalog = BTreeMap<String, ModuleDescription>;

/// A module type whose binary is on the module path but failed to describe itself.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BrokenType {
    pub module_type: String,
    pub binary: String,
    pub error: String,
}

/// One binary of the module path, described or not.
#[derive(Clone, Debug)]
pub enum Entry {
    Described(ModuleDescription),
    Broken(BrokenType),
}

impl Entry {
    pub fn module_type(&self) -> &str {
        match self {
            Entry::Described(description) => &description.module_type,
            Entry::Broken(broken) => &broken.module_type,
        }
    }
}

#[derive(Debug)]
pub struct Palette {
    pub entries: Vec<Entry>,
    /// Binaries found, and how many have answered so far.
    pub total: usize,
    pub done: usize,
    receiver: Option<Receiver<Entry>>,
    /// The module types described so far, for the canvas and the checks.
    pub catalog: Catalog,
    pub broken: Vec<BrokenType>,
}

impl Palette {
    /// A palette with these descriptions and no probing.
    pub fn from_descriptions(descriptions: impl IntoIterator<Item = ModuleDescription>) -> Palette {
        let mut palette = Palette::empty();
        for description in descriptions {
            palette.add(Entry::Described(description));
        }
        palette
    }

    fn empty() -> Palette {
        Palette {
            entries: Vec::new(),
            total: 0,
            done: 0,
            receiver: None,
            catalog: Catalog::new(),
            broken: Vec::new(),
        }
    }

    /// Starts describing every module binary in `folders` in the background.
    pub fn probe(folders: &[PathBuf], timeout: Duration) -> Palette {
        let binaries = probe::list_modules(folders);
        let mut palette = Palette::empty();
        palette.total = binaries.len();
        let (sender, receiver) = channel();
        let cache = probe::ProbeCache::from_env();
        for binary in binaries {
            let sender = sender.clone();
            let cache = cache.clone();
            // One thread per binary: each waits on a child process, and a slow one must not hold
            // the others up. There are a few dozen binaries at most.
            let spawned = std::thread::Builder::new()
                .name("probe".into())
                .spawn(move || {
                    let described = match &cache {
                        Some(cache) => cache.probe(&binary, timeout),
                        None => probe::probe(&binary, timeout),
                    };
                    let entry = match described {
                        Ok(description) => Entry::Described(description),
                        Err(err) => Entry::Broken(BrokenType {
                            module_type: probe::type_from_file_name(&binary)
                                .unwrap_or("?")
                                .to_owned(),
                            binary: binary.display().to_string(),
                            error: err.to_string(),
                        }),
                    };
                    // The studio may have closed the palette meanwhile: nothing to tell then.
                    let _ = sender.send(entry);
                });
            if let Err(err) = spawned {
                tracing::error!("cannot start a probe thread: {err}");
                palette.total -= 1;
            }
        }
        palette.receiver = Some(receiver);
        palette
    }

    pub fn is_probing(&self) -> bool {
        self.receiver.is_some()
    }

    /// Takes what the probes have found since the last call; true if anything changed.
    pub fn poll(&mut self) -> bool {
        let Some(receiver) = &self.receiver else {
            return false;
        };
        let mut arrived = Vec::new();
        let finished = loop {
            match receiver.try_recv() {
                Ok(entry) => arrived.push(entry),
                Err(TryRecvError::Empty) => break self.done + arrived.len() >= self.total,
                Err(TryRecvError::Disconnected) => break true,
            }
        };
        let changed = !arrived.is_empty() || finished;
        for entry in arrived {
            self.done += 1;
            self.add(entry);
        }
        if finished {
            self.receiver = None;
        }
        changed
    }

    /// Blocks until every probe has answered (tests and the bench).
    pub fn wait(&mut self) {
        while let Some(receiver) = &self.receiver {
            match receiver.recv() {
                Ok(entry) => {
                    self.done += 1;
                    self.add(entry);
                    if self.done >= self.total {
                        self.receiver = None;
                    }
                }
                Err(_) => self.receiver = None,
            }
        }
    }

    fn add(&mut self, entry: Entry) {
        match &entry {
            Entry::Described(description) => {
                self.catalog
                    .insert(description.module_type.clone(), description.clone());
            }
            Entry::Broken(broken) => self.broken.push(broken.clone()),
        }
        let at = self
            .entries
            .partition_point(|other| other.module_type() < entry.module_type());
        self.entries.insert(at, entry);
    }
}
