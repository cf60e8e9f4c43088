//! A row's partial sums of a frame's conversion (what the frame reports), kept per row.

use super::mc_noise::McRow;

/// Per-row partial sums; reduced in row order so the totals are thread-count independent.
#[derive(Clone, Copy, Default)]
pub(super) struct RowStats {
    pub expected: f64,
    pub max_expected: f64,
    pub collected: f64,
    pub full: u64,
    pub low: u64,
    pub high: u64,
    /// Sum of the codes (exact in an integer, whatever the order).
    pub dn: u64,
    pub mc: McRow,
}
