// Epoch sweep statistics: folds one epoch's hard-shadow band (from shadow_march.wgsl) into the
// per-cell running statistics (lit-epoch count, current and longest dark run, ever lit).
// Dispatch: one invocation per band cell, 1-D index gid.x + gid.y * (num_workgroups.x * 64);
// workgroups (min(ceil(n/64), 65535), ceil(ceil(n/64) / 65535)). Bindings: 0 shadow (u32), 1 stats.
// Precision: integer counts only (u32, exact up to 4.29e9 epochs). CPU twin: `sweep_accumulate`.

const WORKGROUP_SIZE: u32 = 64u;
const LIT: u32 = 1u;
const NODATA: u32 = 255u;

// Keep in sync with `CellStats` in src/shadow/gpu_twins.rs and src/gpu/sweep_accumulate.rs.
struct CellStats {
    lit_epochs: u32,
    dark_run_epochs: u32,
    longest_dark_run_epochs: u32,
    ever_lit: u32,
}

@group(0) @binding(0) var<storage, read> shadow: array<u32>;
@group(0) @binding(1) var<storage, read_write> stats: array<CellStats>;

@compute @workgroup_size(WORKGROUP_SIZE, 1, 1)
fn sweep_accumulate(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let cell = gid.x + gid.y * groups.x * WORKGROUP_SIZE;
    if cell >= arrayLength(&shadow) {
        return;
    }
    let state = shadow[cell];
    if state == NODATA {
        return;
    }
    var s = stats[cell];
    if state == LIT {
        s.lit_epochs = s.lit_epochs + 1u;
        s.dark_run_epochs = 0u;
        s.ever_lit = 1u;
    } else {
        s.dark_run_epochs = s.dark_run_epochs + 1u;
        s.longest_dark_run_epochs = max(s.longest_dark_run_epochs, s.dark_run_epochs);
    }
    stats[cell] = s;
}
