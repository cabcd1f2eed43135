//! Declarative scenarios (`scenarios/*.toml`): sites, epochs, kernels, DEM layers and outputs.
