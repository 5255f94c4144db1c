//! The one context the window hands every view each frame (rerun's `ViewerContext` is the
//! model): what the views share and none of them owns. A view takes what it needs from it and
//! never reaches into another view's state for it.

use std::collections::BTreeMap;
use std::path::PathBuf;

use armor_protocol::ModuleState;

use crate::common::palette::{Catalog, Palette};

/// What a view knows of the rest of the studio during one frame.
pub struct ViewerContext<'a> {
    /// The module types found on the module path.
    pub palette: &'a Palette,
    /// The system document's file, once it has one.
    pub system_file: Option<PathBuf>,
    /// The state of each module of the run the Run view watches (empty when none runs).
    pub module_states: &'a BTreeMap<String, ModuleState>,
    /// This is the window's first frame.
    pub first_frame: bool,
}

impl ViewerContext<'_> {
    /// The descriptions of the module types that described themselves.
    pub fn catalog(&self) -> &Catalog {
        &self.palette.catalog
    }
}
