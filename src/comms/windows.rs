//! DTE windows: runs of consecutive epochs with a link, as a CSV table and an iCalendar file.
//!
//! Weighting as in `stats.json` (`crate::illum::stats`): sample `k` stands for
//! `[t_k, t_k + step)`, so a run of `m` samples is a window from its first epoch to `m · step`
//! later (±1 step).

use std::io::Write;
use std::path::Path;

use hifitime::{Duration, Epoch};

use super::Station;
use crate::output::OutputError;

/// One DTE window.
#[derive(Debug, Clone, PartialEq)]
pub struct LinkWindow {
    /// First epoch with a link.
    pub start: Epoch,
    /// End of the last sample's interval.
    pub end: Epoch,
    /// Length, hours.
    pub duration_h: f64,
    /// The stations that were best during the window, each once, in the order they first served
    /// (joined by `+` in files).
    pub stations: Vec<String>,
}

/// The windows of a link series: `dte[k]` the link at epoch `start + k · step_s`, `station[k]`
/// the best station's index.
pub fn link_windows(
    dte: &[bool],
    station: &[Option<usize>],
    stations: &[Station],
    start: Epoch,
    step_s: f64,
) -> Vec<LinkWindow> {
    let at = |k: usize| start + Duration::from_seconds(k as f64 * step_s);
    let mut out = Vec::new();
    let mut k = 0;
    while k < dte.len() {
        if !dte[k] {
            k += 1;
            continue;
        }
        let first = k;
        let mut names: Vec<String> = Vec::new();
        while k < dte.len() && dte[k] {
            if let Some(i) = station[k] {
                let n = stations[i].name();
                if !names.iter().any(|m| m == n) {
                    names.push(n.to_string());
                }
            }
            k += 1;
        }
        out.push(LinkWindow {
            start: at(first),
            end: at(k),
            duration_h: (k - first) as f64 * step_s / 3600.0,
            stations: names,
        });
    }
    out
}

fn io_err(path: &Path) -> impl Fn(std::io::Error) -> OutputError + '_ {
    move |source| OutputError::Io {
        path: path.display().to_string(),
        source,
    }
}

/// Writes `start_utc,end_utc,duration_h,stations` rows, atomically.
pub fn write_windows_csv(path: &Path, windows: &[LinkWindow]) -> Result<(), OutputError> {
    crate::output::write_atomic(path, |w: &mut dyn Write| {
        let e = io_err(path);
        writeln!(w, "start_utc,end_utc,duration_h,stations").map_err(&e)?;
        for win in windows {
            writeln!(
                w,
                "{},{},{:.4},{}",
                crate::ephem::time::format_iso(win.start),
                crate::ephem::time::format_iso(win.end),
                win.duration_h,
                win.stations.join("+")
            )
            .map_err(&e)?;
        }
        Ok(())
    })
}

/// An iCalendar `DATE-TIME` in UTC (`20250101T000000Z`), rounded to the second.
fn ics_time(e: Epoch) -> String {
    let (y, mo, d, h, mi, s, ns) = e.to_gregorian_utc();
    let s = if ns >= 500_000_000 { s + 1 } else { s };
    // A rounded 60th second stays on the same minute only at a leap second; carry otherwise.
    let base = Epoch::from_gregorian_utc(y, mo, d, h, mi, 0, 0) + Duration::from_seconds(s as f64);
    let (y, mo, d, h, mi, s, _) = base.to_gregorian_utc();
    format!("{y:04}{mo:02}{d:02}T{h:02}{mi:02}{s:02}Z")
}

/// iCalendar TEXT escaping (RFC 5545 §3.3.11).
fn ics_text(s: &str) -> String {
    s.replace('\\', "\\\\")
        .replace(';', "\\;")
        .replace(',', "\\,")
        .replace('\n', "\\n")
}

/// One event of an iCalendar file ([`write_ics`]).
#[derive(Debug, Clone)]
pub struct IcsEvent {
    /// Start (UTC).
    pub start: Epoch,
    /// End (UTC).
    pub end: Epoch,
    /// A name unique within the file (made into the UID with the start).
    pub id: String,
    /// The event's title.
    pub summary: String,
}

/// Writes `events` as an iCalendar file (RFC 5545) a planner's calendar imports. Deterministic
/// (each stamp is its event's start), so a rerun writes the same bytes.
pub fn write_ics(path: &Path, product: &str, events: &[IcsEvent]) -> Result<(), OutputError> {
    crate::output::write_atomic(path, |w: &mut dyn Write| {
        let e = io_err(path);
        let mut line = |s: &str| -> std::io::Result<()> {
            // Fold lines longer than 75 octets (RFC 5545 §3.1), at character boundaries.
            let mut cur = 0;
            let mut first = true;
            for (i, ch) in s.char_indices() {
                let limit = if first { 75 } else { 74 };
                if i - cur + ch.len_utf8() > limit {
                    w.write_all(&s.as_bytes()[cur..i])?;
                    w.write_all(b"\r\n ")?;
                    cur = i;
                    first = false;
                }
            }
            w.write_all(&s.as_bytes()[cur..])?;
            w.write_all(b"\r\n")
        };
        line("BEGIN:VCALENDAR").map_err(&e)?;
        line("VERSION:2.0").map_err(&e)?;
        line(&format!("PRODID:-//penumbra//{product}//EN")).map_err(&e)?;
        line("CALSCALE:GREGORIAN").map_err(&e)?;
        for ev in events {
            let start = ics_time(ev.start);
            line("BEGIN:VEVENT").map_err(&e)?;
            line(&format!("UID:penumbra-{}-{start}", ics_text(&ev.id))).map_err(&e)?;
            line(&format!("DTSTAMP:{start}")).map_err(&e)?;
            line(&format!("DTSTART:{start}")).map_err(&e)?;
            line(&format!("DTEND:{}", ics_time(ev.end))).map_err(&e)?;
            line(&format!("SUMMARY:{}", ics_text(&ev.summary))).map_err(&e)?;
            line("END:VEVENT").map_err(&e)?;
        }
        line("END:VCALENDAR").map_err(&e)
    })
}

/// Writes the DTE windows of `site` as an iCalendar file: one event per window, named after the
/// site and its stations.
pub fn write_windows_ics(
    path: &Path,
    site: &str,
    windows: &[LinkWindow],
) -> Result<(), OutputError> {
    let events: Vec<IcsEvent> = windows
        .iter()
        .enumerate()
        .map(|(i, win)| IcsEvent {
            start: win.start,
            end: win.end,
            id: format!("dte-{site}-{i}"),
            summary: format!("DTE {site} via {}", win.stations.join("+")),
        })
        .collect();
    write_ics(path, "direct-to-Earth windows", &events)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn windows_are_runs_with_their_stations() {
        let st = crate::comms::dsn(10.0).unwrap();
        let dte = [false, true, true, false, true, true, true];
        let idx = [None, Some(0), Some(0), None, Some(0), Some(1), Some(0)];
        let start = Epoch::from_gregorian_utc_at_midnight(2025, 1, 1);
        let w = link_windows(&dte, &idx, &st, start, 3600.0);
        assert_eq!(w.len(), 2);
        assert_eq!(w[0].start, start + Duration::from_seconds(3600.0));
        assert_eq!(w[0].duration_h, 2.0);
        assert_eq!(w[1].stations, vec!["DSS-14", "DSS-43"]);
        assert_eq!(w[1].end, start + Duration::from_seconds(7.0 * 3600.0));
        assert_eq!(ics_time(w[1].end), "20250101T070000Z");
    }
}
