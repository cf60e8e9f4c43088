//! `hilcam serve`: the real-time loop from pose to frame on the wire (tokio shell over the
//! synchronous renderer).

pub mod extrapolate;
pub mod governor;
