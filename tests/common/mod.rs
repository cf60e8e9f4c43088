//! Fixtures shared by the rendering tests.
#![allow(dead_code)]

pub mod frames;
pub mod logs;
pub mod scenes;
pub mod shipped;
pub mod soup;
