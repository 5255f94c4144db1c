//! Where a file named in another file is: a world, a base map or a system named in a plan, a
//! file a module reads named in a system (a parameter declared `file` in its description).
//!
//! A relative name is looked for, in this order, next to the file that names it, in each
//! folder of the module path, then in `assets/FOLDER/` (the kind of file: `worlds`, `maps`)
//! of the naming file's folder and every folder above it, of the folders above the `armor`
//! executable (an installed or built tree: `target/release/armor` finds the workspace's
//! `assets/`), and last of the current folder. So a plan or a system works the same from any
//! current folder, and the name a module gets is one it can open wherever it runs.

use std::path::{Path, PathBuf};

/// Where the file or folder `name`, written in a file in the folder `referrer_dir`, is; `Err`
/// says where it was looked for.
pub fn resolve(
    name: &str,
    referrer_dir: &Path,
    module_path: &[PathBuf],
    assets_folder: &str,
) -> Result<PathBuf, String> {
    let given = Path::new(name);
    if given.is_absolute() {
        return if given.exists() {
            Ok(given.to_path_buf())
        } else {
            Err(format!("`{name}` does not exist"))
        };
    }
    let candidates = candidates(given, referrer_dir, module_path, assets_folder);
    if let Some(found) = candidates.iter().find(|candidate| candidate.exists()) {
        return Ok(std::path::absolute(found).unwrap_or_else(|_| found.clone()));
    }
    Err(format!(
        "cannot find `{name}`: looked next to the file that names it ({}), in the module path, \
         then in assets/{assets_folder}/ of that folder and the folders above it, of the armor \
         installation and of the current folder",
        referrer_dir.display()
    ))
}

/// Every place [`resolve`] looks for a relative name, in order.
fn candidates(
    given: &Path,
    referrer_dir: &Path,
    module_path: &[PathBuf],
    assets_folder: &str,
) -> Vec<PathBuf> {
    let mut candidates = vec![referrer_dir.join(given)];
    candidates.extend(module_path.iter().map(|folder| folder.join(given)));
    let assets = Path::new("assets").join(assets_folder);
    let mut roots: Vec<PathBuf> = Vec::new();
    let referrer = std::fs::canonicalize(referrer_dir).unwrap_or_else(|_| referrer_dir.into());
    roots.extend(referrer.ancestors().map(Path::to_path_buf));
    if let Some(exe_dir) = std::env::current_exe()
        .ok()
        .and_then(|exe| exe.parent().map(Path::to_path_buf))
    {
        roots.extend(exe_dir.ancestors().map(Path::to_path_buf));
    }
    if let Ok(cwd) = std::env::current_dir() {
        roots.push(cwd);
    }
    let mut seen = std::collections::HashSet::new();
    for root in roots {
        if seen.insert(root.clone()) {
            candidates.push(root.join(&assets).join(given));
        }
    }
    candidates
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_naming_files_folder_comes_first_then_the_module_path_then_assets() {
        let root = tempfile::tempdir().expect("temporary folder");
        let plans = root.path().join("deep/plans");
        let modules = root.path().join("modules");
        let worlds = root.path().join("assets/worlds");
        for folder in [&plans, &modules, &worlds] {
            std::fs::create_dir_all(folder).expect("folder");
        }
        std::fs::write(worlds.join("a.world"), "assets").expect("write");
        std::fs::write(modules.join("a.world"), "modules").expect("write");
        let found = |name: &str| {
            resolve(name, &plans, std::slice::from_ref(&modules), "worlds")
                .map(|path| std::fs::read_to_string(path).expect("read"))
        };
        assert_eq!(found("a.world").as_deref(), Ok("modules"));
        std::fs::write(plans.join("a.world"), "beside").expect("write");
        assert_eq!(found("a.world").as_deref(), Ok("beside"));
        std::fs::write(worlds.join("b.world"), "assets b").expect("write");
        assert_eq!(found("b.world").as_deref(), Ok("assets b"));
        let missing = found("c.world").expect_err("not there");
        assert!(missing.contains("cannot find `c.world`"), "{missing}");
        assert!(missing.contains("assets/worlds/"), "{missing}");
    }
}
