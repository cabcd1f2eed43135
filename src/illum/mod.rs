//! Illumination: visible fractions of the Sun's and the Earth's discs, irradiance, statistics.
