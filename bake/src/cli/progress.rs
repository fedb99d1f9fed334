//! Terminal progress for bakes: a spinner per product being baked, a line per finished product.
//! Spinners appear only on a terminal; lines go to stderr either way (unless quiet).

use indicatif::{MultiProgress, ProgressBar, ProgressStyle};
use otbake::pipeline::bake::{Event, Status};
use std::cell::RefCell;
use std::io::IsTerminal;
use std::time::Duration;

/// Progress display of one bake.
pub struct Progress {
    lines: bool,
    multi: Option<MultiProgress>,
    current: RefCell<Option<ProgressBar>>,
}

impl Progress {
    /// A display; `lines = false` shows nothing.
    pub fn new(lines: bool) -> Self {
        let multi = (lines && std::io::stderr().is_terminal()).then(MultiProgress::new);
        Self {
            lines,
            multi,
            current: RefCell::new(None),
        }
    }

    /// Shows one bake event.
    pub fn event(&self, e: &Event<'_>) {
        if !self.lines {
            return;
        }
        match e {
            Event::Started { name } => {
                if let Some(multi) = &self.multi {
                    let bar = multi.add(ProgressBar::new_spinner());
                    bar.set_style(
                        ProgressStyle::with_template("{spinner} baking {msg} ({elapsed})")
                            .unwrap_or_else(|_| ProgressStyle::default_spinner()),
                    );
                    bar.set_message(name.to_string());
                    bar.enable_steady_tick(Duration::from_millis(120));
                    *self.current.borrow_mut() = Some(bar);
                }
            }
            Event::Finished(p) => {
                if let Some(bar) = self.current.borrow_mut().take() {
                    bar.finish_and_clear();
                }
                let line = format!(
                    "{:<6} {:<12} {:>8.2} s  {}  {}",
                    p.status.name(),
                    p.name,
                    p.seconds,
                    p.path.display(),
                    p.detail
                );
                match (&self.multi, p.status) {
                    (Some(multi), _) => {
                        let _ = multi.println(line);
                    }
                    (None, Status::Failed | Status::Built | Status::Cached) => eprintln!("{line}"),
                }
            }
        }
    }

    /// Clears any spinner left.
    pub fn finish(&self) {
        if let Some(bar) = self.current.borrow_mut().take() {
            bar.finish_and_clear();
        }
    }
}
