//! A region of the sensor (a camera client's ROI) rendered on its own.
//!
//! A window renders only its own pixels, yet each of them is the pixel of the full frame:
//! the primary rays go through the same sensor coordinates (the view's principal point is
//! moved, not the rays), and every random number is keyed by the pixel's index on the
//! full sensor ([`PixelKeys`]). With uniform sampling a window's radiance is therefore
//! the full frame's radiance there, bit for bit (`tests/render/window.rs`).

use super::CameraModel;

/// Pixels `[x, x + width) × [y, y + height)` of a `CameraModel`'s array.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Window {
    pub x: u32,
    pub y: u32,
    pub width: u32,
    pub height: u32,
}

/// A window that does not fit the sensor.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
#[error("window {width}x{height} at ({x}, {y}) is not inside the {sensor_w}x{sensor_h} sensor (or is empty)")]
pub struct WindowError {
    pub x: u32,
    pub y: u32,
    pub width: u32,
    pub height: u32,
    pub sensor_w: u32,
    pub sensor_h: u32,
}

impl Window {
    /// The whole array of `camera`.
    pub fn full(camera: &CameraModel) -> Window {
        Window { x: 0, y: 0, width: camera.width, height: camera.height }
    }

    /// `self`, checked to be non-empty and inside `camera`'s array.
    pub fn inside(self, camera: &CameraModel) -> Result<Window, WindowError> {
        let fits = |o: u32, n: u32, of: u32| n > 0 && u64::from(o) + u64::from(n) <= u64::from(of);
        if fits(self.x, self.width, camera.width) && fits(self.y, self.height, camera.height) {
            Ok(self)
        } else {
            let Window { x, y, width, height } = self;
            Err(WindowError { x, y, width, height, sensor_w: camera.width, sensor_h: camera.height })
        }
    }

    pub fn is_full(&self, camera: &CameraModel) -> bool {
        *self == Window::full(camera)
    }

    pub fn pixels(&self) -> u64 {
        u64::from(self.width) * u64::from(self.height)
    }

    /// `self` grown by `mx` columns and `my` rows on every side, clipped to `camera`.
    pub fn grown(&self, mx: u32, my: u32, camera: &CameraModel) -> Window {
        let (x, y) = (self.x.saturating_sub(mx), self.y.saturating_sub(my));
        let x1 = (self.x + self.width).saturating_add(mx).min(camera.width);
        let y1 = (self.y + self.height).saturating_add(my).min(camera.height);
        Window { x, y, width: x1 - x, height: y1 - y }
    }

    /// Where `inner` (a window of the same sensor, inside `self`) sits within `self`.
    pub fn relative(&self, inner: &Window) -> Window {
        Window { x: inner.x - self.x, y: inner.y - self.y, ..*inner }
    }
}

/// The random-number key of each pixel of an image: its index on the full sensor.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PixelKeys {
    x: u32,
    y: u32,
    /// Columns of the full sensor.
    stride: u32,
}

impl PixelKeys {
    /// The keys of an image that is the whole array, `width` columns wide.
    pub fn full(width: u32) -> PixelKeys {
        PixelKeys { x: 0, y: 0, stride: width }
    }

    /// The keys of `window` of a sensor `sensor_width` columns wide.
    pub fn window(window: &Window, sensor_width: u32) -> PixelKeys {
        PixelKeys { x: window.x, y: window.y, stride: sensor_width }
    }

    /// The keys of `window` of an image with these keys.
    pub fn shifted(&self, window: &Window) -> PixelKeys {
        PixelKeys { x: self.x + window.x, y: self.y + window.y, stride: self.stride }
    }

    /// Sensor row of the image's row 0.
    pub fn first_row(&self) -> u32 {
        self.y
    }

    /// Key of the image's pixel (`row`, `col`).
    #[inline]
    pub fn key(&self, row: u32, col: u32) -> u64 {
        u64::from(row + self.y) * u64::from(self.stride) + u64::from(col + self.x)
    }

    /// Where the image's pixel (`row`, `col`) is on the full sensor.
    #[inline]
    pub fn on_sensor(&self, row: u32, col: u32) -> (u32, u32) {
        (row + self.y, col + self.x)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cam(w: u32, h: u32) -> CameraModel {
        CameraModel { width: w, height: h, pitch_um: 5.5, focal_mm: 20.0, principal_point_px: [0.0; 2] }
    }

    #[test]
    fn windows_outside_the_sensor_or_empty_are_refused() {
        let c = cam(64, 48);
        assert!(Window { x: 0, y: 0, width: 64, height: 48 }.inside(&c).is_ok());
        assert!(Window { x: 60, y: 0, width: 8, height: 8 }.inside(&c).is_err());
        assert!(Window { x: 0, y: 0, width: 0, height: 8 }.inside(&c).is_err());
        assert!(Window { x: u32::MAX, y: 0, width: 2, height: 8 }.inside(&c).is_err());
        let e = Window { x: 0, y: 40, width: 8, height: 9 }.inside(&c).unwrap_err();
        assert_eq!(e.to_string(), "window 8x9 at (0, 40) is not inside the 64x48 sensor (or is empty)");
    }

    #[test]
    fn grown_windows_stop_at_the_sensor_edge_and_keys_are_sensor_indices() {
        let c = cam(64, 48);
        let w = Window { x: 2, y: 40, width: 10, height: 6 };
        let g = w.grown(3, 3, &c);
        assert_eq!(g, Window { x: 0, y: 37, width: 15, height: 11 });
        assert_eq!(g.relative(&w), Window { x: 2, y: 3, width: 10, height: 6 });
        let k = PixelKeys::window(&w, 64);
        assert_eq!(k.key(0, 0), 40 * 64 + 2);
        assert_eq!(k.key(1, 3), 41 * 64 + 5);
        assert_eq!(PixelKeys::full(64).key(1, 3), 67);
        let inner = Window { x: 1, y: 2, width: 3, height: 3 };
        assert_eq!(k.shifted(&inner).key(0, 0), 42 * 64 + 3, "a window of a window");
    }
}
