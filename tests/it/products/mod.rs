//! What penumbra writes (`src/products/`): maps and per-site series through the library and the
//! binary.

mod map;
mod series;
