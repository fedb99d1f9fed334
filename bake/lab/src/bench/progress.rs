//! Progress of a benchmark on stderr.

use super::Event;
use std::io::IsTerminal;

/// Progress on stderr: a bar on a terminal, one line per finished run either way.
pub struct TerminalProgress {
    bar: Option<indicatif::ProgressBar>,
}

impl Default for TerminalProgress {
    fn default() -> Self {
        Self::new()
    }
}

impl TerminalProgress {
    /// A display with no bar yet (it appears at [`Event::Planned`] on a terminal).
    pub fn new() -> Self {
        Self { bar: None }
    }

    /// Shows one event.
    pub fn event(&mut self, e: Event<'_>) {
        match e {
            Event::Planned { runs } => {
                if std::io::stderr().is_terminal() {
                    let bar = indicatif::ProgressBar::new(runs as u64);
                    bar.set_style(
                        indicatif::ProgressStyle::with_template(
                            "{bar:30} {pos}/{len} runs ({elapsed}, ~{eta} left) {msg}",
                        )
                        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
                    );
                    bar.enable_steady_tick(std::time::Duration::from_millis(200));
                    self.bar = Some(bar);
                }
            }
            Event::Preparing { case, n } => {
                if let Some(bar) = &self.bar {
                    bar.set_message(format!("sampling {case} n={n}"));
                }
            }
            Event::Started {
                case,
                solver,
                settings,
                n,
            } => {
                if let Some(bar) = &self.bar {
                    bar.set_message(format!("{case} n={n} {solver} {settings}"));
                }
            }
            Event::Finished(r) => {
                let f = |v: Option<f64>| v.map_or("-".into(), |v| format!("{v:.3}"));
                let line = format!(
                    "{:<9} {:<8} {:<32} n={:<7} {:>8.3} s  cost/exact {:<6} uvp% {:<7} {}",
                    r.case,
                    r.solver,
                    r.settings,
                    r.n,
                    r.seconds,
                    f(r.cost_ratio),
                    f(r.uvp()),
                    match &r.error {
                        None if r.converged => "ok".to_string(),
                        None => "not converged".to_string(),
                        Some(e) => format!("error: {e}"),
                    }
                );
                match &self.bar {
                    Some(bar) => {
                        bar.println(line);
                        bar.inc(1);
                    }
                    None => eprintln!("{line}"),
                }
            }
        }
    }

    /// Removes the bar.
    pub fn finish(&mut self) {
        if let Some(bar) = self.bar.take() {
            bar.finish_and_clear();
        }
    }
}
