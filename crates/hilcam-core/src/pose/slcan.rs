//! slcan (Lawicel ASCII) line codec: what cheap USB-CAN adapters speak over a
//! (virtual) serial line. Pure functions plus an incremental line splitter.
//!
//! Frames: `tIIILDD…\r` (11-bit), `TIIIIIIIILDD…\r` (29-bit), `r`/`R` remote
//! frames, and the CANable-2 FD variants `d`/`D` (FD) and `b`/`B` (FD with bit
//! rate switch), where `L` is the DLC code (FD: 0–F). An optional 4-hex-digit
//! timestamp may follow the data. Commands: `Sn` (bit rate), `O` (open),
//! `C` (close); the adapter replies `\r` (ok) or BEL (error).

use super::can::{CanFrame, FD_LENGTHS};

/// Longest valid line (`D` + 8 id + 1 dlc + 128 data + 4 timestamp), plus slack.
pub const MAX_LINE: usize = 160;

/// Lawicel `Sn` code for a classic bit rate, e.g. 500 000 → 6.
pub fn bitrate_code(bps: u32) -> Option<u8> {
    const RATES: [u32; 9] = [10_000, 20_000, 50_000, 100_000, 125_000, 250_000, 500_000, 800_000, 1_000_000];
    RATES.iter().position(|&r| r == bps).map(|i| i as u8)
}

/// One parsed line from an adapter.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SlcanItem {
    /// A received data frame.
    Frame(CanFrame),
    /// A remote (RTR) frame: carries no data for hilcam.
    Remote {
        /// Identifier.
        id: u32,
    },
    /// Empty line: the adapter acknowledged a command.
    Ack,
    /// BEL: the adapter rejected a command.
    Nack,
    /// `z`/`Z` transmit acknowledgement or another reply hilcam ignores
    /// (version `V…`, serial `N…`, status `F…`).
    Reply,
}

/// Why a line is not valid slcan.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum SlcanError {
    /// Unknown first character.
    #[error("unknown slcan command {0:#04x}")]
    UnknownCommand(u8),
    /// A character that should be hex is not.
    #[error("non-hex digit in slcan frame")]
    BadHex,
    /// Identifier, DLC or line length inconsistent.
    #[error("slcan frame has a bad identifier, DLC or length")]
    BadFrame,
    /// No `\r` within [`MAX_LINE`] bytes.
    #[error("slcan line longer than {MAX_LINE} bytes")]
    TooLong,
}

impl SlcanError {
    /// Stable snake_case name for logs and metric labels.
    pub fn as_str(&self) -> &'static str {
        match self {
            SlcanError::UnknownCommand(_) => "unknown_command",
            SlcanError::BadHex => "bad_hex",
            SlcanError::BadFrame => "bad_frame",
            SlcanError::TooLong => "too_long",
        }
    }
}

fn hex(digits: &[u8]) -> Result<u32, SlcanError> {
    digits.iter().try_fold(0u32, |acc, &c| {
        let v = (c as char).to_digit(16).ok_or(SlcanError::BadHex)?;
        Ok(acc << 4 | v)
    })
}

/// Parses one line without its terminator.
///
/// # Errors
/// [`SlcanError`] for anything that is not a well-formed frame or reply.
pub fn decode_line(line: &[u8]) -> Result<SlcanItem, SlcanError> {
    let Some(&c) = line.first() else {
        return Ok(SlcanItem::Ack);
    };
    let (id_len, extended, fd, brs, remote) = match c {
        b't' => (3, false, false, false, false),
        b'T' => (8, true, false, false, false),
        b'r' => (3, false, false, false, true),
        b'R' => (8, true, false, false, true),
        b'd' => (3, false, true, false, false),
        b'D' => (8, true, true, false, false),
        b'b' => (3, false, true, true, false),
        b'B' => (8, true, true, true, false),
        b'z' | b'Z' | b'V' | b'v' | b'N' | b'F' => return Ok(SlcanItem::Reply),
        other => return Err(SlcanError::UnknownCommand(other)),
    };
    if line.len() < 2 + id_len {
        return Err(SlcanError::BadFrame);
    }
    let id = hex(&line[1..1 + id_len])?;
    let dlc = hex(&line[1 + id_len..2 + id_len])? as usize;
    let len = if fd {
        FD_LENGTHS[dlc]
    } else if dlc <= 8 {
        dlc
    } else {
        return Err(SlcanError::BadFrame);
    };
    let rest = &line[2 + id_len..];
    if remote {
        // Remote frames carry no data; an optional timestamp may follow.
        return match rest.len() {
            0 | 4 => Ok(SlcanItem::Remote { id }),
            _ => Err(SlcanError::BadFrame),
        };
    }
    if rest.len() != 2 * len && rest.len() != 2 * len + 4 {
        return Err(SlcanError::BadFrame);
    }
    hex(&rest[2 * len..])?; // timestamp, if any, must still be hex
    let mut data = [0u8; 64];
    for (i, d) in data.iter_mut().take(len).enumerate() {
        *d = hex(&rest[2 * i..2 * i + 2])? as u8;
    }
    let frame =
        if fd { CanFrame::new_fd(id, extended, &data[..len], brs) } else { CanFrame::new(id, extended, &data[..len]) };
    frame.map(SlcanItem::Frame).ok_or(SlcanError::BadFrame)
}

/// The line (with `\r`) that transmits `f`.
pub fn encode_frame(f: &CanFrame) -> String {
    use std::fmt::Write;
    let d = f.data();
    let c = match (f.fd, f.brs, f.extended) {
        (false, _, false) => 't',
        (false, _, true) => 'T',
        (true, false, false) => 'd',
        (true, false, true) => 'D',
        (true, true, false) => 'b',
        (true, true, true) => 'B',
    };
    let dlc = if f.fd { FD_LENGTHS.iter().position(|&l| l == d.len()).expect("legal FD length") } else { d.len() };
    let mut s = String::with_capacity(2 + 8 + 2 * d.len() + 1);
    s.push(c);
    if f.extended {
        let _ = write!(s, "{:08X}", f.id);
    } else {
        let _ = write!(s, "{:03X}", f.id);
    }
    let _ = write!(s, "{dlc:X}");
    for b in d {
        let _ = write!(s, "{b:02X}");
    }
    s.push('\r');
    s
}

/// Splits an adapter's byte stream into lines (`\r` or BEL terminated; `\n`
/// ignored) and parses them.
#[derive(Debug, Default)]
pub struct SlcanDecoder {
    line: Vec<u8>,
    overflow: bool,
    pending: std::collections::VecDeque<Result<SlcanItem, SlcanError>>,
}

impl SlcanDecoder {
    /// An empty decoder.
    pub fn new() -> Self {
        Self::default()
    }

    /// Feeds bytes; parsed items queue up for [`Self::next_item`].
    pub fn push(&mut self, bytes: &[u8]) {
        for &b in bytes {
            match b {
                b'\r' => {
                    let item = if self.overflow { Err(SlcanError::TooLong) } else { decode_line(&self.line) };
                    self.pending.push_back(item);
                    self.line.clear();
                    self.overflow = false;
                }
                0x07 => {
                    self.pending.push_back(Ok(SlcanItem::Nack));
                    self.line.clear();
                    self.overflow = false;
                }
                b'\n' => {}
                _ if self.line.len() >= MAX_LINE => self.overflow = true,
                _ => self.line.push(b),
            }
        }
    }

    /// The next parsed line, if any.
    pub fn next_item(&mut self) -> Option<Result<SlcanItem, SlcanError>> {
        self.pending.pop_front()
    }
}
