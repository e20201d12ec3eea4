//! Progress bars for long work (drawn on stderr, hidden when it is not a terminal).

use std::sync::Mutex;

use indicatif::{MultiProgress, ProgressBar, ProgressStyle};

use prt_gpu::bake::Progress;

/// Every progress bar of the run, drawn together on stderr (hidden when stderr is not a
/// terminal): a batch's bar over all its meshes, and the bar of the stage running.
pub(crate) fn bars() -> &'static MultiProgress {
    static BARS: std::sync::OnceLock<MultiProgress> = std::sync::OnceLock::new();
    BARS.get_or_init(MultiProgress::new)
}

/// The bar over a whole batch, above each mesh's stage bars: its length is the meshes' work
/// (`scene::batch::work_weights`), so its rate and eta follow the bytes baked, not the count.
pub(crate) fn batch_bar(total: u64) -> ProgressBar {
    let bar = bars().add(ProgressBar::new(total));
    bar.set_style(
        ProgressStyle::with_template("{msg:>10} [{bar:40}] {percent}%, eta {eta}")
            .expect("static template")
            .progress_chars("=> "),
    );
    bar
}

/// A progress bar on stderr; indicatif hides it when stderr is not a terminal.
#[derive(Default)]
pub(crate) struct BarProgress {
    /// The running stage's bar and its name (its message before any detail).
    bar: Mutex<Option<(ProgressBar, String)>>,
    /// In a batch, which mesh of how many: "[2/5] bunny".
    prefix: String,
}

impl Progress for BarProgress {
    fn stage(&self, name: &str, total: u64) {
        let name = format!("{}{name}", self.prefix);
        let bar = bars().add(ProgressBar::new(total).with_message(name.clone()));
        bar.set_style(
            ProgressStyle::with_template("{msg:>10} [{bar:40}] {pos}/{len}, eta {eta}")
                .expect("static template")
                .progress_chars("=> "),
        );
        // Redrawn on a clock: a draw that comes within indicatif's rate limit of the last is
        // dropped, so a stage begun just after another ended would show only at its first step.
        bar.enable_steady_tick(std::time::Duration::from_millis(250));
        if let Some(old) = self
            .bar
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .replace((bar, name))
        {
            old.0.finish_and_clear();
        }
    }

    fn advance(&self, done: u64) {
        if let Some((bar, _)) = self.bar.lock().unwrap_or_else(|e| e.into_inner()).as_ref() {
            bar.inc(done);
        }
    }

    fn detail(&self, text: &str) {
        if let Some((bar, name)) = self.bar.lock().unwrap_or_else(|e| e.into_inner()).as_ref() {
            match text {
                "" => bar.set_message(name.clone()),
                text => bar.set_message(format!("{name} {text}")),
            }
        }
    }
}

impl BarProgress {
    pub(crate) fn in_batch(position: usize, count: usize, mesh: &str) -> BarProgress {
        BarProgress {
            prefix: format!("[{position}/{count}] {mesh} "),
            ..BarProgress::default()
        }
    }

    pub(crate) fn finish(&self) {
        if let Some((bar, _)) = self.bar.lock().unwrap_or_else(|e| e.into_inner()).take() {
            bar.finish_and_clear();
        }
    }
}
