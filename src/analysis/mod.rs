//! Histogram analysis (in progress).
