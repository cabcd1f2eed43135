//! Ephemerides: the Sun's and the Earth's topocentric directions in `MOON_ME`.
