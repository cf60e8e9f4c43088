//! Pose input, one binary (each binary links the whole crate): the serial, CAN and slcan
//! codecs, validation, trajectories, the receivers over real pseudo-terminals, and the
//! worked examples of docs/protocol.md. SocketCAN has its own binary (`can_socketcan`:
//! it runs inside the vcan VM).
//! `cargo test --test pose`; one file: `cargo test --test pose serial_pty::`.

#[path = "../common/mod.rs"]
mod common;
#[path = "../pose_common/mod.rs"]
mod pose_common;

mod codec;
mod docs_protocol;
mod random_stream;
mod rig_time;
mod serial_pty;
mod slcan_pty;
mod trajectories;
mod validate;
