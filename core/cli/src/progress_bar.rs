//! Runs long work on a thread and shows its progress on stderr (a bar on a terminal,
//! nothing otherwise); Ctrl-C cancels it.

use std::io::IsTerminal;
use std::sync::Arc;
use std::time::Duration;

use indicatif::{ProgressBar, ProgressStyle};
use relume_engine::progress::Progress;

/// Runs `work` with a shared [`Progress`], drawing a bar labelled `label` meanwhile.
pub fn with_progress<T: Send + 'static>(
    label: &str,
    work: impl FnOnce(Arc<Progress>) -> T + Send + 'static,
) -> T {
    let progress = Arc::new(Progress::new());
    {
        let p = progress.clone();
        // A second handler cannot be installed; the first command's is enough.
        let _ = ctrlc::set_handler(move || p.cancel());
    }
    let worker = {
        let p = progress.clone();
        std::thread::spawn(move || work(p))
    };
    let bar = std::io::stderr().is_terminal().then(|| {
        let bar = ProgressBar::new(1000);
        bar.set_style(
            ProgressStyle::with_template(
                "{msg} [{bar:40}] {percent:>3}% {elapsed_precise} ETA {eta}",
            )
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
        );
        bar.set_message(label.to_string());
        bar
    });
    while !worker.is_finished() {
        if let Some(bar) = &bar {
            bar.set_position((progress.fraction() * 1000.0) as u64);
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    if let Some(bar) = bar {
        bar.finish_and_clear();
    }
    match worker.join() {
        Ok(v) => v,
        Err(panic) => std::panic::resume_unwind(panic),
    }
}
