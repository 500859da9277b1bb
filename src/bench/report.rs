//! Where bench figures go: Markdown tables for people, or with `--json` one
//! JSON object per line per case for scripts. Every case carries the driver
//! and, for ray-tracing cases, its ratio to the floor kernel of the same run.

use std::collections::BTreeMap;

use serde::Serialize;

/// One measured case, as `--json` prints it.
#[derive(Debug, Clone, Serialize)]
pub struct Case {
    pub case: String,
    /// Milliseconds per frame (or per ray batch, for ray cases).
    pub ms: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mrays_per_s: Option<f64>,
    /// `ms` divided by `floor_1`'s ms in the same run.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub floor_ratio: Option<f64>,
    /// GPU milliseconds per kernel (timestamp queries), where measured.
    pub kernels: BTreeMap<String, f64>,
    pub driver: String,
}

pub struct Report {
    pub json: bool,
    pub driver: String,
    /// floor_1's ms, once timed: the denominator of every floor_ratio.
    pub floor_1: Option<f64>,
}

impl Report {
    /// A human-readable line (tables, headings): printed unless `--json`.
    pub fn line(&self, text: std::fmt::Arguments) {
        if !self.json {
            out!("{text}");
        }
    }

    /// A named case: a JSON line with `--json`, nothing otherwise (the
    /// tables carry the same figures).
    pub fn case(&self, name: &str, ms: f64, mrays_per_s: Option<f64>, kernels: &[(&str, f64)]) {
        if !self.json {
            return;
        }
        // Three decimals: timings are not repeatable beyond that anyway.
        let round = |x: f64| (x * 1e3).round() / 1e3;
        let case = Case {
            case: name.to_string(),
            ms: round(ms),
            mrays_per_s: mrays_per_s.map(round),
            floor_ratio: self.floor_1.map(|f| round(ms / f)),
            kernels: kernels
                .iter()
                .filter(|(_, ms)| ms.is_finite())
                .map(|(k, ms)| (k.to_string(), round(*ms)))
                .collect(),
            driver: self.driver.clone(),
        };
        match serde_json::to_string(&case) {
            Ok(text) => out!("{text}"),
            Err(e) => log::error!("bench case {name}: {e}"),
        }
    }

    /// A case that could not run here, and why (e.g. a missing model).
    pub fn skipped(&self, name: &str, reason: &str) {
        if self.json {
            out!(
                "{}",
                serde_json::json!({ "case": name, "skipped": reason, "driver": self.driver })
            );
        } else {
            out!("{name}: skipped: {reason}");
        }
    }
}

/// `report.line(format_args!(...))` in short.
macro_rules! md {
    ($report:expr, $($arg:tt)*) => {
        $report.line(format_args!($($arg)*))
    };
}
pub(crate) use md;
