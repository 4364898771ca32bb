//! What a running sweep tells its caller, and asks it: progress, whether to
//! stop, each finished chunk.

use crate::error::Result;
use crate::sim::result::CellResult;

/// Callbacks from a running sweep.
pub trait Hooks {
    /// `steps` more cell-steps are done.
    fn progress(&mut self, _steps: u64) {}
    /// True to stop now; checked about every 50 ms of simulation work.
    fn should_stop(&mut self) -> bool {
        false
    }
    /// A chunk of cells finished (in grid order within the chunk).
    fn chunk_done(&mut self, _results: &[CellResult]) -> Result<()> {
        Ok(())
    }
}

/// Hooks that do nothing.
pub struct NoHooks;
impl Hooks for NoHooks {}
