#![no_main]
//! Arbitrary datagrams at the GigE Vision control port: the decoder never panics, a
//! rejected command is answered with an error acknowledge exactly when its header was
//! readable, and every accepted command respects the codec's bounds.
use hilcam_fuzz::gvcp::{self, Command};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    match gvcp::decode(data) {
        Ok(req) => match &req.command {
            Command::ReadReg(a) => assert!(!a.is_empty() && a.len() <= gvcp::MAX_REGS),
            Command::WriteReg(p) => assert!(!p.is_empty() && p.len() <= gvcp::MAX_REGS),
            Command::ReadMem { count, .. } => assert!(*count % 4 == 0 && u32::from(*count) <= gvcp::MAX_MEM_BLOCK),
            Command::WriteMem { data, .. } => assert!(data.len() % 4 == 0 && data.len() as u32 <= gvcp::MAX_MEM_BLOCK),
            Command::PacketResend { .. } | Command::Discovery => {}
        },
        Err(rejected) => {
            let ack = gvcp::reject_ack(&rejected);
            assert_eq!(ack.is_some(), rejected.reply_to.is_some());
            if let Some(ack) = ack {
                let a = gvcp::decode_ack(&ack).expect("our acknowledge decodes");
                assert_eq!(a.status, rejected.status.code());
                assert!(a.status & 0x8000 != 0);
            }
        }
    }
});
