//! Reading a system file from disk and checking it against the module binaries it names.

use std::collections::BTreeMap;
use std::fmt;
use std::path::{Path, PathBuf};

use armor_model::{ModuleInstance, SystemConfig};
use armor_module_api::ModuleDescription;
use armor_module_api::protocol::ModuleConfig;
use armor_module_api::xml::{Located, Pos};

use crate::{paths, probe};

/// A checked system and the descriptions of its module types.
#[derive(Clone, Debug)]
pub struct Loaded {
    pub system: SystemConfig,
    pub descriptions: BTreeMap<String, ModuleDescription>,
}

impl Loaded {
    /// The configuration a module instance gets from the config server.
    pub fn module_config(&self, module: &ModuleInstance) -> Option<ModuleConfig> {
        let description = self.descriptions.get(&module.module_type);
        let bindings = self.system.bindings(&module.name, description)?;
        Some(ModuleConfig {
            module_type: bindings.module_type,
            inputs: bindings.inputs,
            outputs: bindings.outputs,
            params: bindings.params,
            active: true,
            host: self.system.bind_address(module),
            input_rates: self.system.input_rates(&module.name),
        })
    }
}

/// Every problem of a file, printed one per line as `FILE:LINE:COL: message`.
#[derive(Debug)]
pub struct Diagnostics {
    pub file: PathBuf,
    pub problems: Vec<Located>,
}

impl fmt::Display for Diagnostics {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, problem) in self.problems.iter().enumerate() {
            if i > 0 {
                writeln!(f)?;
            }
            write!(
                f,
                "{}:{}: {}",
                self.file.display(),
                problem.pos,
                problem.message
            )?;
        }
        Ok(())
    }
}

impl std::error::Error for Diagnostics {}

/// A file's text, or a diagnostic saying why it cannot be read.
pub fn read_source(file: &Path) -> Result<String, Diagnostics> {
    std::fs::read_to_string(file).map_err(|err| Diagnostics {
        file: file.to_path_buf(),
        problems: vec![Located::new(
            Pos { line: 1, col: 1 },
            format!("cannot read the file: {err}"),
        )],
    })
}

/// Reads, parses and checks a system file; probes the module types it uses on `module_path`.
pub fn load_system(file: &Path, module_path: &[PathBuf]) -> Result<Loaded, Diagnostics> {
    let fail = |problems| Diagnostics {
        file: file.to_path_buf(),
        problems,
    };
    let text = read_source(file)?;
    let mut system = SystemConfig::parse(&text).map_err(fail)?;
    let used = || {
        system
            .modules
            .iter()
            .map(|module| module.module_type.as_str())
    };
    let (mut descriptions, failures) = probe::describe_types(module_path, used());
    if used().any(|module_type| !descriptions.contains_key(module_type)) {
        // An unknown type is often a typo: describe everything on the path, so that the message
        // lists every type the user could have meant.
        let everything = probe::list_modules(module_path);
        for (_, result) in probe::probe_all_cached(&everything, probe::DEFAULT_TIMEOUT) {
            if let Ok(description) = result {
                descriptions
                    .entry(description.module_type.clone())
                    .or_insert(description);
            }
        }
    }
    let mut problems = armor_model::check(&system, &descriptions);
    // A binary that exists but cannot describe itself is reported where its type is named
    // (the model check has already said the type is unknown; say why).
    for (module_type, binary, err) in failures {
        for module in system
            .modules
            .iter()
            .filter(|m| m.module_type == module_type)
        {
            problems.push(Located::new(
                module.type_pos,
                format!("module `{}`: {}: {err}", module.name, binary.display()),
            ));
        }
    }
    let folder = file.parent().unwrap_or_else(|| Path::new("."));
    problems.extend(resolve_files(
        &mut system,
        &descriptions,
        folder,
        module_path,
    ));
    problems.sort_by_key(|problem| problem.pos);
    if problems.is_empty() {
        Ok(Loaded {
            system,
            descriptions,
        })
    } else {
        Err(fail(problems))
    }
}

/// Replaces the value of every parameter that names a file (declared `file` in its module's
/// description) by the path of the file it names, found from `folder` (the system file's) as
/// [`paths::resolve`] says, so that a module opens it whatever its current folder; a file that
/// cannot be found or read is a problem at the value.
fn resolve_files(
    system: &mut SystemConfig,
    descriptions: &BTreeMap<String, ModuleDescription>,
    folder: &Path,
    module_path: &[PathBuf],
) -> Vec<Located> {
    let mut problems = Vec::new();
    for module in &mut system.modules {
        let Some(description) = descriptions.get(&module.module_type) else {
            continue;
        };
        for param in &mut module.params {
            let Some(assets_folder) = description
                .param(&param.name)
                .and_then(|spec| spec.file.as_deref())
            else {
                continue;
            };
            let name = param.value.trim();
            if name.is_empty() {
                continue;
            }
            let found = paths::resolve(name, folder, module_path, assets_folder).and_then(|path| {
                std::fs::File::open(&path)
                    .map(|_| path.clone())
                    .map_err(|err| format!("cannot read `{}`: {err}", path.display()))
            });
            match found {
                Ok(path) => param.value = path.display().to_string(),
                Err(message) => problems.push(Located::new(
                    param.value_pos,
                    format!(
                        "module `{}`: parameter `{}`: {message}",
                        module.name, param.name
                    ),
                )),
            }
        }
    }
    problems
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_module_placed_on_a_host_binds_there_and_its_links_carry_their_rates() {
        let system = SystemConfig::parse(
            "<system name=\"s\" host=\"10.0.0.1\">\n<host name=\"robot1\" address=\"10.0.0.2\"/>\n<module name=\"a\" type=\"t\" host=\"robot1\"/>\n<module name=\"b\" type=\"t\"/>\n<link from=\"b.x\" to=\"a.scan\" max_rate_hz=\"4\"/>\n</system>",
        )
        .expect("valid");
        let loaded = Loaded {
            system,
            descriptions: BTreeMap::new(),
        };
        let a = loaded.module_config(&loaded.system.modules[0]).expect("a");
        let b = loaded.module_config(&loaded.system.modules[1]).expect("b");
        assert_eq!(a.host, "10.0.0.2");
        assert_eq!(a.input_rates, [("scan".to_owned(), 4.0)].into());
        assert_eq!(b.host, "10.0.0.1");
        assert!(b.input_rates.is_empty());
    }
}
