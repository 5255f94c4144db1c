//! The undo history and the outcome of an edit, shared by the System view's diagram editor and
//! the Mission view's plan editor.

/// How many steps Ctrl+Z can go back.
const HISTORY_LIMIT: usize = 200;

/// Snapshots of the document before each edit: whole copies. A diagram of a thousand blocks is
/// a few hundred kilobytes, so 200 steps stay within tens of megabytes, and copies cannot get
/// out of step with the edits the way inverse operations can. Both editors, the System view's diagram
/// and the Mission view's plan, keep their history this way.
#[derive(Debug)]
pub struct History<T> {
    undo: Vec<T>,
    redo: Vec<T>,
}

impl<T> Default for History<T> {
    fn default() -> Self {
        Self {
            undo: Vec::new(),
            redo: Vec::new(),
        }
    }
}

impl<T> History<T> {
    pub fn record(&mut self, before: T) {
        self.undo.push(before);
        if self.undo.len() > HISTORY_LIMIT {
            self.undo.remove(0);
        }
        self.redo.clear();
    }

    pub fn can_undo(&self) -> bool {
        !self.undo.is_empty()
    }

    pub fn can_redo(&self) -> bool {
        !self.redo.is_empty()
    }

    pub fn undo(&mut self, current: &mut T) -> bool {
        match self.undo.pop() {
            Some(before) => {
                self.redo.push(std::mem::replace(current, before));
                true
            }
            None => false,
        }
    }

    pub fn redo(&mut self, current: &mut T) -> bool {
        match self.redo.pop() {
            Some(after) => {
                self.undo.push(std::mem::replace(current, after));
                true
            }
            None => false,
        }
    }
}

/// What applying a command did, for the status line.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Outcome {
    Nothing,
    Done(String),
    Refused(String),
}
