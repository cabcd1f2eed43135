//! Shadow engines on the model-space height field (CPU reference implementations).
pub mod gpu_twins;
