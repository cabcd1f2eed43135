//! Terrain horizons: elevation of the horizon as a function of azimuth for an observer.
