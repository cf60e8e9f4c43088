//! Slow writes: what a write the renderer applies at its next frame waits for a
//! published frame to show before its final acknowledge (pending acknowledge).
//!
//! Pure: `device.rs` records what each published frame shows ([`Shown`]) and waits for
//! the [`Awaited`] of a write.

use super::registers::{CameraSettings, Effect};
use super::request::{integration_override, roi};
use crate::frame::EncodedFrame;
use crate::render::camera::Window;

/// What a published frame shows of the client's settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Shown {
    /// Its integration time (s).
    pub integration_s: f32,
    /// The region it was rendered for (None: the whole sensor).
    pub roi: Option<Window>,
}

impl Shown {
    pub fn of(frame: &EncodedFrame) -> Self {
        Shown { integration_s: frame.meta.integration_s, roi: frame.roi }
    }
}

/// What a slow write waits for: each `Some` must be what a frame shows.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Awaited {
    /// A manual integration time (s) the client wrote.
    pub integration_s: Option<f32>,
    /// The region after the write (`Some(None)`: the whole sensor).
    pub roi: Option<Option<Window>>,
}

impl Awaited {
    /// What the writes with `effects` that left the device at `settings` wait for, or
    /// None when nothing (a write applied to the next frame sent, or an exposure handed
    /// to the auto-exposure, whose time is not known in advance). `initial`: the
    /// settings the device started with.
    pub fn of(initial: &CameraSettings, settings: &CameraSettings, effects: &[Effect]) -> Option<Self> {
        let integration_s =
            integration_override(initial, settings).filter(|_| effects.contains(&Effect::Exposure)).map(|t| t as f32);
        let roi = effects.contains(&Effect::Roi).then(|| roi(initial, settings));
        (integration_s.is_some() || roi.is_some()).then_some(Awaited { integration_s, roi })
    }

    pub fn shown_by(&self, f: &Shown) -> bool {
        self.integration_s.is_none_or(|t| same_integration(f.integration_s, t)) && self.roi.is_none_or(|r| r == f.roi)
    }
}

/// Whether a frame's integration time is the one a client wrote (f32 µs → s).
fn same_integration(frame_s: f32, target_s: f32) -> bool {
    (frame_s - target_s).abs() <= target_s * 1e-4
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_write_waits_for_its_own_state() {
        let cam = crate::sink::gige::registers::tests::camera();
        let full = CameraSettings { exposure_auto: false, ..CameraSettings::initial(&cam) };
        let narrow = CameraSettings { width: 32, ..full };
        let a = Awaited::of(&full, &narrow, &[Effect::Roi]).expect("an ROI write is slow");
        assert_eq!(a, Awaited { integration_s: None, roi: Some(Some(Window { x: 0, y: 0, width: 32, height: 48 })) });
        let roi = Some(Window { x: 0, y: 0, width: 32, height: 48 });
        assert!(a.shown_by(&Shown { integration_s: 1e-3, roi }));
        assert!(!a.shown_by(&Shown { integration_s: 1e-3, roi: None }), "a whole-sensor frame is not the ROI");
        // Back to the whole sensor: waits for a frame without an ROI.
        let back = Awaited::of(&full, &full, &[Effect::Roi]).unwrap();
        assert!(
            back.shown_by(&Shown { integration_s: 1e-3, roi: None })
                && !back.shown_by(&Shown { integration_s: 1e-3, roi })
        );
        // Exposure: the written time; auto-exposure: nothing to wait for.
        let e = CameraSettings { exposure_us: 250.0, ..full };
        let a = Awaited::of(&full, &e, &[Effect::Exposure]).unwrap();
        assert!(
            a.shown_by(&Shown { integration_s: 250e-6, roi: None })
                && !a.shown_by(&Shown { integration_s: 1e-3, roi: None })
        );
        let auto = CameraSettings { exposure_auto: true, ..full };
        assert_eq!(Awaited::of(&full, &auto, &[Effect::Exposure]), None);
        assert_eq!(Awaited::of(&full, &narrow, &[Effect::Settings]), None, "pixel format, chunks: not slow");
    }
}
