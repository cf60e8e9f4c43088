//! Little-endian field readers/writers shared by the codecs (no I/O, no panics on
//! short input: callers check lengths first).

use glam::{DQuat, DVec3};

/// Appends little-endian fields to a byte vector.
pub(crate) struct Writer<'a>(pub &'a mut Vec<u8>);

impl Writer<'_> {
    pub fn u8(&mut self, v: u8) {
        self.0.push(v);
    }
    pub fn u16(&mut self, v: u16) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    pub fn u32(&mut self, v: u32) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    pub fn u64(&mut self, v: u64) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    pub fn f64(&mut self, v: f64) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    pub fn f32(&mut self, v: f32) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    pub fn i16(&mut self, v: i16) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    /// Low three bytes of a two's-complement i32 (range checked by the caller).
    pub fn i24(&mut self, v: i32) {
        self.0.extend_from_slice(&v.to_le_bytes()[..3]);
    }
    pub fn dvec3_f64(&mut self, v: DVec3) {
        self.f64(v.x);
        self.f64(v.y);
        self.f64(v.z);
    }
    pub fn dvec3_f32(&mut self, v: DVec3) {
        self.f32(v.x as f32);
        self.f32(v.y as f32);
        self.f32(v.z as f32);
    }
    /// Scalar first: w, x, y, z.
    pub fn dquat_f64(&mut self, q: DQuat) {
        self.f64(q.w);
        self.f64(q.x);
        self.f64(q.y);
        self.f64(q.z);
    }
}

/// Reads little-endian fields from a slice whose length the caller has checked.
pub(crate) struct Reader<'a> {
    buf: &'a [u8],
    pos: usize,
}

impl<'a> Reader<'a> {
    pub fn new(buf: &'a [u8]) -> Self {
        Reader { buf, pos: 0 }
    }
    fn take<const N: usize>(&mut self) -> [u8; N] {
        let mut out = [0u8; N];
        out.copy_from_slice(&self.buf[self.pos..self.pos + N]);
        self.pos += N;
        out
    }
    pub fn u8(&mut self) -> u8 {
        self.take::<1>()[0]
    }
    pub fn u32(&mut self) -> u32 {
        u32::from_le_bytes(self.take())
    }
    pub fn u64(&mut self) -> u64 {
        u64::from_le_bytes(self.take())
    }
    pub fn f64(&mut self) -> f64 {
        f64::from_le_bytes(self.take())
    }
    pub fn f32(&mut self) -> f32 {
        f32::from_le_bytes(self.take())
    }
    pub fn i16(&mut self) -> i16 {
        i16::from_le_bytes(self.take())
    }
    /// Sign-extends three little-endian bytes.
    pub fn i24(&mut self) -> i32 {
        let b = self.take::<3>();
        i32::from_le_bytes([b[0], b[1], b[2], 0]) << 8 >> 8
    }
    pub fn dvec3_f64(&mut self) -> DVec3 {
        DVec3::new(self.f64(), self.f64(), self.f64())
    }
    pub fn dvec3_f32(&mut self) -> DVec3 {
        DVec3::new(self.f32() as f64, self.f32() as f64, self.f32() as f64)
    }
    pub fn dquat_f64(&mut self) -> DQuat {
        let (w, x, y, z) = (self.f64(), self.f64(), self.f64(), self.f64());
        DQuat::from_xyzw(x, y, z, w)
    }
}
