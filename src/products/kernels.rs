//! `penumbra kernels`: what the loaded SPICE kernels hold.

use std::fmt::Write as _;

use super::KernelSource;
use crate::ephem::time::format_utc;

/// The report of `penumbra kernels`: files (size, sha256), SPK bodies and their spans, frames and
/// the usable epoch span.
pub fn report(source: &KernelSource) -> anyhow::Result<String> {
    let kernels = source.load()?;
    let mut out = String::new();
    let origin = match &source.dir {
        Some(dir) => format!("--kernels {}", dir.display()),
        None => crate::ephem::kernels::default_kernel_source().1,
    };
    writeln!(
        out,
        "kernel source: {origin}\n  (first of: --kernels DIR|FILE.tm or a scenario's `kernels`, \
         $PENUMBRA_KERNELS, the set built into penumbra)"
    )?;
    match &kernels.meta_kernel {
        Some(mk) => writeln!(out, "meta-kernel: {}", mk.display())?,
        None => writeln!(out, "kernel folder: {}", kernels.dir.display())?,
    }
    for f in &kernels.files {
        writeln!(
            out,
            "  {:<4} {:>10} B  sha256 {}  {}",
            f.kind,
            f.size_bytes,
            &f.sha256[..16],
            f.path.display()
        )?;
    }
    for f in &kernels.skipped {
        writeln!(out, "  skipped {}: {}", f.path.display(), f.why)?;
    }
    writeln!(out, "bodies (SPK, NAIF id: span TDB):")?;
    let mut domains: Vec<_> = kernels
        .almanac
        .spk_domains()
        .map(|d| d.into_iter().collect())
        .unwrap_or_default();
    domains.sort_by_key(|(id, _)| *id);
    for (id, (s, e)) in domains.into_iter().filter(|(id, _)| *id != 0) {
        writeln!(out, "  {:>4} {}: {} .. {}", id, body_name(id), s, e)?;
    }
    let f = kernels.frames;
    writeln!(
        out,
        "frames: J2000 (1), {} ({}, binary PCK), MOON_ME = {} ({}, from the frame kernels)",
        f.pa_name, f.pa_id, f.me_name, f.me_id
    )?;
    if let Ok((s, e)) = kernels.almanac.bpc_domain(f.pa_id) {
        writeln!(out, "  {} orientation data: {s} .. {e}", f.pa_name)?;
    }
    writeln!(
        out,
        "usable epochs (all bodies and MOON_ME, light-time margin included): {} .. {} UTC",
        format_utc(kernels.coverage.0),
        format_utc(kernels.coverage.1)
    )?;
    writeln!(
        out,
        "time scales: UTC input, leap seconds from hifitime's table (= naif0012), TDB for the kernels"
    )?;
    Ok(out)
}

/// The NAIF name of a body or barycentre id ("" when unknown).
fn body_name(id: i32) -> &'static str {
    match id {
        0 => "solar-system barycentre",
        3 => "Earth-Moon barycentre",
        10 => "Sun",
        301 => "Moon",
        399 => "Earth",
        1 => "Mercury barycentre",
        2 => "Venus barycentre",
        4 => "Mars barycentre",
        5 => "Jupiter barycentre",
        6 => "Saturn barycentre",
        7 => "Uranus barycentre",
        8 => "Neptune barycentre",
        9 => "Pluto barycentre",
        _ => "",
    }
}
