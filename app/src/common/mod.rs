//! What the views share, so that no view reaches into another's files: the module types found
//! on the module path ([`palette`]), the undo history ([`history`]), the per-frame context the
//! window hands every view ([`context`]), drawing helpers ([`draw`]) and the placement of labels
//! on a map ([`labels`]).

pub mod context;
pub mod draw;
pub mod history;
pub mod labels;
pub mod palette;
