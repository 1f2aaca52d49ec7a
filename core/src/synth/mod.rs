//! Synthetic photogrammetry-like models with a known true colour everywhere.
