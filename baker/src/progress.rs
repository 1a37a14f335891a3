//! Progress reports of the baker's long stages (geometry, bake): the one trait the
//! command line draws its bars from. Called from worker threads; every method has a
//! no-op default.

use std::time::Instant;

pub trait Progress: Sync {
    /// A stage starts; `total` units of work (rows, images, clusters) follow.
    fn begin(&self, _stage: &str, _total: u64) {}
    /// `n` more units of the current stage are done.
    fn advance(&self, _n: u64) {}
    /// The stage is done, after `seconds` of wall time.
    fn end(&self, _stage: &str, _seconds: f64) {}
}

/// A [`Progress`] that reports nothing.
pub struct NoProgress;
impl Progress for NoProgress {}

/// A stage under way: begun when made, ended (with its wall time) by [`Stage::finish`]
/// or when dropped, so an early return by `?` still ends it.
pub struct Stage<'p> {
    progress: &'p dyn Progress,
    name: String,
    start: Instant,
}

/// Begins stage `name` of `total` units on `progress`.
pub fn stage<'p>(progress: &'p dyn Progress, name: impl Into<String>, total: u64) -> Stage<'p> {
    let name = name.into();
    progress.begin(&name, total);
    Stage { progress, name, start: Instant::now() }
}

impl Stage<'_> {
    pub fn advance(&self, n: u64) {
        self.progress.advance(n);
    }

    /// Ends the stage; returns its wall time in seconds.
    pub fn finish(self) -> f64 {
        self.start.elapsed().as_secs_f64()
    }
}

impl Drop for Stage<'_> {
    fn drop(&mut self) {
        self.progress.end(&self.name, self.start.elapsed().as_secs_f64());
    }
}
