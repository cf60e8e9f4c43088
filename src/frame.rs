//! A rendered frame with the metadata that travels with it (stream and recorder).

/// How the payload's pixels are encoded (little-endian, row-major, no padding).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PixelFormat {
    Mono8,
    /// 16-bit container; the sensor's bit depth (10/12/16) is in the metadata.
    Mono16,
    /// Entrance-pupil radiance, W·sr⁻¹·m⁻², f32.
    Float32,
}
