//! Radiance images (W·sr⁻¹·m⁻² in the band) and writing them to files.

/// A single-channel float image, row-major, `data[row * width + col]`.
#[derive(Clone, Debug, PartialEq)]
pub struct RadianceImage {
    pub width: u32,
    pub height: u32,
    pub data: Vec<f32>,
}

impl RadianceImage {
    pub fn new(width: u32, height: u32, fill: f32) -> Self {
        RadianceImage {
            width,
            height,
            data: vec![fill; width as usize * height as usize],
        }
    }

    pub fn get(&self, col: u32, row: u32) -> f32 {
        self.data[row as usize * self.width as usize + col as usize]
    }
}
