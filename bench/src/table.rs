//! The bench's tables: percentile rows (every latency figure of the benchmarks is one [`Row`]:
//! count, p50, p99, p99.9, max in µs, printed aligned and serialised as is to JSON), the
//! aligned table of any columns ([`table`]) and word-wrapped notes ([`note`]).

use hdrhistogram::Histogram;
use lop_ipc::Percentiles;
use serde::Serialize;

/// One measured quantity.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Row {
    /// Stable machine name (JSON consumers key on it).
    pub key: String,
    /// What the table shows.
    pub label: String,
    /// Samples.
    pub count: u64,
    /// Median, µs.
    pub p50_us: f64,
    /// 99th percentile, µs.
    pub p99_us: f64,
    /// 99.9th percentile, µs.
    pub p999_us: f64,
    /// Largest sample, µs.
    pub max_us: f64,
    /// How many devices the haptic loop drove, for the rows measured at several counts
    /// (`lop-bench latency --devices N`: `haptic_compute`, `haptic_jitter`); absent elsewhere.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub devices: Option<u32>,
}

fn ns_to_us(ns: u64) -> f64 {
    ns as f64 / 1000.0
}

impl Row {
    /// From the daemon's percentiles (ns).
    pub fn from_percentiles(key: &str, label: &str, p: &Percentiles) -> Row {
        Row {
            key: key.into(),
            label: label.into(),
            count: p.count,
            p50_us: ns_to_us(p.p50),
            p99_us: ns_to_us(p.p99),
            p999_us: ns_to_us(p.p999),
            max_us: ns_to_us(p.max),
            devices: None,
        }
    }

    /// From a histogram of nanoseconds.
    pub fn from_histogram_ns(key: &str, label: &str, h: &Histogram<u64>) -> Row {
        if h.is_empty() {
            return Row::from_percentiles(key, label, &Percentiles::default());
        }
        Row {
            key: key.into(),
            label: label.into(),
            count: h.len(),
            p50_us: ns_to_us(h.value_at_quantile(0.5)),
            p99_us: ns_to_us(h.value_at_quantile(0.99)),
            p999_us: ns_to_us(h.value_at_quantile(0.999)),
            max_us: ns_to_us(h.max()),
            devices: None,
        }
    }

    /// The same row, measured with `devices` devices.
    pub fn with_devices(self, devices: u32) -> Row {
        Row {
            devices: Some(devices),
            ..self
        }
    }
}

/// A histogram for latencies in ns: 0 ns .. 60 s, 3 significant digits.
pub fn latency_histogram() -> Histogram<u64> {
    Histogram::new_with_max(60_000_000_000, 3).expect("constant histogram bounds are valid")
}

const LABEL_W: usize = 36;
const COUNT_W: usize = 8;
const NUM_W: usize = 9;

/// The header line of a percentile table.
pub fn header() -> String {
    format!(
        "{:<LABEL_W$} {:>COUNT_W$} {:>NUM_W$} {:>NUM_W$} {:>NUM_W$} {:>NUM_W$}   (µs)",
        "quantity", "count", "p50", "p99", "p99.9", "max"
    )
}

fn num(v: f64) -> String {
    if v >= 100_000.0 {
        format!("{v:.0}")
    } else if v < 10.0 {
        format!("{v:.2}")
    } else {
        format!("{v:.1}")
    }
}

/// One aligned table line; a row without samples shows dashes.
pub fn line(row: &Row) -> String {
    let label: String = if row.label.chars().count() > LABEL_W {
        row.label.chars().take(LABEL_W).collect()
    } else {
        row.label.clone()
    };
    if row.count == 0 {
        return format!(
            "{label:<LABEL_W$} {:>COUNT_W$} {:>NUM_W$} {:>NUM_W$} {:>NUM_W$} {:>NUM_W$}",
            0, "-", "-", "-", "-"
        );
    }
    format!(
        "{label:<LABEL_W$} {:>COUNT_W$} {:>NUM_W$} {:>NUM_W$} {:>NUM_W$} {:>NUM_W$}",
        row.count,
        num(row.p50_us),
        num(row.p99_us),
        num(row.p999_us),
        num(row.max_us)
    )
}

/// The header and one line per row.
pub fn render(rows: &[Row]) -> String {
    let mut out = header();
    for r in rows {
        out.push('\n');
        out.push_str(&line(r));
    }
    out
}

/// A bulleted note ("  - …"), word-wrapped at `width` columns with continuation lines
/// indented under the text; ends with a newline.
pub fn note(text: &str, width: usize) -> String {
    let mut out = String::new();
    let mut line = String::from("  -");
    for word in text.split_whitespace() {
        if line.chars().count() + 1 + word.chars().count() > width && line.trim() != "-" {
            out.push_str(&line);
            out.push('\n');
            line = String::from("   ");
        }
        line.push(' ');
        line.push_str(word);
    }
    out.push_str(&line);
    out.push('\n');
    out
}

/// Column alignment.
#[derive(Clone, Copy)]
pub enum Align {
    Left,
    Right,
}

/// An aligned text table of any columns: a header line, then one line per row, columns two
/// spaces apart, each as wide as its widest cell. (The percentile table above keeps fixed
/// widths so the latency tables of different runs line up.)
pub fn table(headers: &[(&str, Align)], rows: &[Vec<String>]) -> String {
    let mut w: Vec<usize> = headers.iter().map(|h| h.0.chars().count()).collect();
    for r in rows {
        for (k, c) in r.iter().enumerate() {
            if k < w.len() {
                w[k] = w[k].max(c.chars().count());
            }
        }
    }
    let line = |cells: Vec<&str>| {
        let mut s = String::new();
        for (k, c) in cells.iter().enumerate() {
            let pad = w[k].saturating_sub(c.chars().count());
            if k > 0 {
                s.push_str("  ");
            }
            match headers[k].1 {
                Align::Left => {
                    s.push_str(c);
                    if k + 1 < cells.len() {
                        s.push_str(&" ".repeat(pad));
                    }
                }
                Align::Right => {
                    s.push_str(&" ".repeat(pad));
                    s.push_str(c);
                }
            }
        }
        let mut s = s.trim_end().to_string();
        s.push('\n');
        s
    };
    let mut out = line(headers.iter().map(|h| h.0).collect());
    for r in rows {
        out += &line(r.iter().map(|c| c.as_str()).collect());
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn notes_wrap_under_their_text() {
        let n = note("one two three four five six", 14);
        assert_eq!(n, "  - one two\n    three four\n    five six\n");
        assert_eq!(note("short", 100), "  - short\n");
    }

    #[test]
    fn histogram_row_is_ordered_and_in_us() {
        let mut h = latency_histogram();
        for v in 1..=1000u64 {
            h.record(v * 1000).unwrap();
        }
        let r = Row::from_histogram_ns("x", "x", &h);
        assert_eq!(r.count, 1000);
        assert!((r.p50_us - 500.0).abs() < 1.0, "{r:?}");
        assert!(r.p50_us <= r.p99_us && r.p99_us <= r.p999_us && r.p999_us <= r.max_us);
        assert!((r.max_us - 1000.0).abs() < 1.0, "{r:?}");
    }

    #[test]
    fn lines_align_with_header() {
        let r = Row {
            key: "k".into(),
            label: "tool → deform latency".into(),
            count: 12,
            p50_us: 1.25,
            p99_us: 10.0,
            p999_us: 123.4,
            max_us: 1234567.0,
            devices: None,
        };
        let empty = Row::from_percentiles("e", "empty", &Percentiles::default());
        let text = render(&[r, empty]);
        let widths: Vec<usize> = text.lines().map(|l| l.chars().count()).collect();
        // Every data line ends where the header's "max" column ends.
        let max_end = header().find("max").unwrap() + 3;
        assert_eq!(widths[1], max_end, "{text}");
        assert_eq!(widths[2], max_end, "{text}");
        assert!(text.contains("tool → deform latency"));
    }

    #[test]
    fn table_aligns_columns() {
        let t = table(
            &[("a", Align::Left), ("bb", Align::Right)],
            &[vec!["xyz".into(), "1".into()]],
        );
        assert_eq!(t, "a    bb\nxyz   1\n");
    }
}
