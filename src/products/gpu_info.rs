//! `penumbra gpu-info`: the adapters wgpu finds, and what a `--backend` choice resolves to.

use crate::gpu::Backend;

/// The line saying what `requested` resolves to (`auto` falls back to the CPU with one warning
/// line, `gpu` fails without an adapter).
pub fn resolved(requested: Backend) -> anyhow::Result<String> {
    let resolved = crate::compute::resolve(requested, crate::compute::OnGpu::Preferred)?;
    Ok(format!(
        "backend {}: {}\n",
        requested.as_str(),
        resolved.describe()
    ))
}

/// The adapters wgpu finds (honours `WGPU_BACKEND`): name, backend, device type, driver and the
/// compute limits that bound penumbra's kernels.
#[cfg(feature = "gpu")]
pub fn adapters() -> anyhow::Result<String> {
    use std::fmt::Write as _;
    let adapters = crate::gpu::adapter_report();
    let mut out = String::new();
    if adapters.is_empty() {
        writeln!(
            out,
            "no GPU adapter found (WGPU_BACKEND={}); --backend auto will use the CPU",
            std::env::var("WGPU_BACKEND").unwrap_or_else(|_| "unset".into())
        )?;
    }
    for (i, a) in adapters.iter().enumerate() {
        writeln!(out, "adapter {i}: {}", a.name)?;
        writeln!(
            out,
            "  backend: {}, device type: {}, driver: {}",
            a.backend, a.device_type, a.driver
        )?;
        writeln!(
            out,
            "  max_storage_buffer_binding_size: {} B",
            a.max_storage_buffer_binding_size
        )?;
        writeln!(out, "  max_buffer_size: {} B", a.max_buffer_size)?;
        writeln!(
            out,
            "  max_compute_workgroup_size_x: {}",
            a.max_compute_workgroup_size_x
        )?;
        writeln!(
            out,
            "  max_compute_invocations_per_workgroup: {}",
            a.max_compute_invocations_per_workgroup
        )?;
        writeln!(
            out,
            "  max_compute_workgroups_per_dimension: {}",
            a.max_compute_workgroups_per_dimension
        )?;
    }
    Ok(out)
}

/// The adapters wgpu finds: none in a build without the `gpu` feature.
#[cfg(not(feature = "gpu"))]
pub fn adapters() -> anyhow::Result<String> {
    Ok("this penumbra was built without the `gpu` cargo feature: no GPU adapters\n".into())
}
