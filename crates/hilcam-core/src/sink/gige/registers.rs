//! The device's register and memory map: GigE Vision bootstrap registers, the GenICam
//! XML file, and hilcam's feature registers. Pure state: reads and writes over
//! addresses, each write validated (out of range → a GigE Vision status, never a
//! panic) and reported as an [`Effect`] for the device shell to act on.
//!
//! All registers are 32-bit big-endian words at 4-byte-aligned addresses. The table of
//! addresses is in `docs/gige.md`; the XML (`genicam.rs`) names the same constants.

use super::chunk::{ChunkKind, ChunkSet};
use super::gvcp::Status;
use super::pixel::GevPixelFormat;
use crate::render::camera::Window;
use std::net::Ipv4Addr;

// Bootstrap registers (GigE Vision), as Aravis names them in arvgvcpprivate.h.
pub const VERSION: u32 = 0x0000;
pub const DEVICE_MODE: u32 = 0x0004;
pub const MAC_HIGH: u32 = 0x0008;
pub const MAC_LOW: u32 = 0x000C;
pub const IP_CONFIG_SUPPORTED: u32 = 0x0010;
pub const IP_CONFIG_CURRENT: u32 = 0x0014;
pub const CURRENT_IP: u32 = 0x0024;
pub const CURRENT_SUBNET: u32 = 0x0034;
pub const CURRENT_GATEWAY: u32 = 0x0044;
pub const MANUFACTURER_NAME: u32 = 0x0048;
pub const MODEL_NAME: u32 = 0x0068;
pub const DEVICE_VERSION: u32 = 0x0088;
pub const MANUFACTURER_INFO: u32 = 0x00A8;
pub const SERIAL_NUMBER: u32 = 0x00D8;
pub const USER_NAME: u32 = 0x00E8;
/// Bytes of bootstrap memory a DISCOVERY_ACK carries.
pub const DISCOVERY_LEN: u32 = 0x00F8;
pub const XML_URL_0: u32 = 0x0200;
pub const XML_URL_1: u32 = 0x0400;
pub const XML_URL_LEN: u32 = 512;
pub const N_INTERFACES: u32 = 0x0600;
pub const N_MESSAGE_CHANNELS: u32 = 0x0900;
pub const N_STREAM_CHANNELS: u32 = 0x0904;
pub const GVCP_CAPABILITY: u32 = 0x0934;
pub const HEARTBEAT_TIMEOUT: u32 = 0x0938;
pub const TICK_FREQ_HIGH: u32 = 0x093C;
pub const TICK_FREQ_LOW: u32 = 0x0940;
pub const TIMESTAMP_CONTROL: u32 = 0x0944;
pub const TIMESTAMP_VALUE_HIGH: u32 = 0x0948;
pub const TIMESTAMP_VALUE_LOW: u32 = 0x094C;
pub const GVCP_CONFIG: u32 = 0x0954;
/// Pending timeout (ms, read-only): the longest a command takes before its final
/// acknowledge when the client has enabled pending acknowledges.
pub const PENDING_TIMEOUT: u32 = 0x0958;
pub const CCP: u32 = 0x0A00;
pub const MCP: u32 = 0x0B00;
pub const MCDA: u32 = 0x0B10;
pub const SCP0: u32 = 0x0D00;
pub const SCPS0: u32 = 0x0D04;
pub const SCPD0: u32 = 0x0D08;
pub const SCDA0: u32 = 0x0D18;
pub const SCSP0: u32 = 0x0D1C;
pub const SCC0: u32 = 0x0D20;
pub const SCCFG0: u32 = 0x0D24;
/// End of the bootstrap block: reserved words below it read as 0.
pub const BOOTSTRAP_END: u32 = 0x1000;

/// Where the GenICam XML file lives in device memory.
pub const XML_BASE: u32 = 0x0001_0000;
/// Room for it (the XML is refused at start-up if larger).
pub const XML_MAX: u32 = 0x0001_0000;

// hilcam feature registers.
pub const FEATURES: u32 = 0x0002_0000;
pub const WIDTH: u32 = FEATURES;
pub const HEIGHT: u32 = FEATURES + 0x04;
pub const OFFSET_X: u32 = FEATURES + 0x08;
pub const OFFSET_Y: u32 = FEATURES + 0x0C;
pub const SENSOR_WIDTH: u32 = FEATURES + 0x10;
pub const SENSOR_HEIGHT: u32 = FEATURES + 0x14;
pub const PIXEL_FORMAT: u32 = FEATURES + 0x18;
pub const PAYLOAD_SIZE: u32 = FEATURES + 0x1C;
pub const ACQUISITION_MODE: u32 = FEATURES + 0x20;
pub const ACQUISITION_START: u32 = FEATURES + 0x24;
pub const ACQUISITION_STOP: u32 = FEATURES + 0x28;
pub const TRIGGER_SELECTOR: u32 = FEATURES + 0x2C;
pub const TRIGGER_MODE: u32 = FEATURES + 0x30;
pub const TRIGGER_SOURCE: u32 = FEATURES + 0x34;
pub const TRIGGER_SOFTWARE: u32 = FEATURES + 0x38;
/// f32 bits, µs.
pub const EXPOSURE_TIME: u32 = FEATURES + 0x3C;
pub const EXPOSURE_AUTO: u32 = FEATURES + 0x40;
/// f32 bits, Hz.
pub const FRAME_RATE: u32 = FEATURES + 0x44;
pub const CHUNK_MODE_ACTIVE: u32 = FEATURES + 0x48;
pub const ACQUISITION_STATUS: u32 = FEATURES + 0x4C;
/// SensorWidth − OffsetX: the widest Width the offsets leave (SFNC WidthMax).
pub const WIDTH_MAX: u32 = FEATURES + 0x50;
pub const HEIGHT_MAX: u32 = FEATURES + 0x54;
/// ExposureMode: Timed (1) is the only mode.
pub const EXPOSURE_MODE: u32 = FEATURES + 0x58;
/// TLParamsLocked: 1 locks the stream-shaping features (see [`Registers::shape_locked`]).
pub const TL_PARAMS_LOCKED: u32 = FEATURES + 0x5C;
/// ChunkSelector (a [`ChunkKind`]) and ChunkEnable of the selected chunk.
pub const CHUNK_SELECTOR: u32 = FEATURES + 0x60;
pub const CHUNK_ENABLE: u32 = FEATURES + 0x64;
/// DeviceFirmwareVersion: a string of [`FIRMWARE_VERSION_LEN`] bytes.
pub const FIRMWARE_VERSION: u32 = FEATURES + 0x100;
pub const FIRMWARE_VERSION_LEN: u32 = 32;
pub const FEATURES_END: u32 = FIRMWARE_VERSION + FIRMWARE_VERSION_LEN;
/// DeviceUserID (bootstrap 0x00E8): 16 bytes, NUL-terminated, so 15 of text.
pub const USER_NAME_LEN: u32 = 16;

/// GVCP capability bits this device implements (register 0x0934).
pub mod capability {
    pub const CONCATENATION: u32 = 1 << 0;
    pub const WRITE_MEMORY: u32 = 1 << 1;
    pub const PACKET_RESEND: u32 = 1 << 2;
    pub const PENDING_ACK: u32 = 1 << 5;
    pub const HEARTBEAT_DISABLE: u32 = 1 << 29;
    pub const SERIAL_NUMBER: u32 = 1 << 30;
}

/// CCP register bits.
pub const CCP_EXCLUSIVE: u32 = 1 << 0;
pub const CCP_CONTROL: u32 = 1 << 1;
/// Timestamp control: latch the current timestamp into the value registers.
pub const TIMESTAMP_LATCH: u32 = 1 << 1;
/// GVCP configuration bit 0: heartbeat disabled.
pub const GVCP_CONFIG_HEARTBEAT_DISABLE: u32 = 1 << 0;
/// GVCP configuration bit 1: the client accepts PENDING_ACK (GigE Vision 2.0); without
/// it a slow write is acknowledged as soon as it is stored.
pub const GVCP_CONFIG_PENDING_ACK_ENABLE: u32 = 1 << 1;
/// SCPS bit 31: fire a test packet (not implemented; the XML does not offer it).
pub const SCPS_FIRE_TEST: u32 = 1 << 31;
pub const SCPS_DO_NOT_FRAGMENT: u32 = 1 << 30;
/// SCPS bit 29: big-endian pixels (refused: pixels are little-endian).
pub const SCPS_BIG_ENDIAN: u32 = 1 << 29;

/// Packet sizes (IP datagram, as the SCPS register counts) the stream accepts.
pub const PACKET_SIZE_MIN: u32 = 576;
pub const PACKET_SIZE_MAX: u32 = 9000;
pub const PACKET_SIZE_INC: u32 = 4;
/// Largest inter-packet delay (SCPD, ticks = ns): 1 ms. A larger one (0xFFFFFFFF is
/// 4.3 s per packet) would stall the stream for minutes per block.
pub const SCPD_MAX_TICKS: u32 = 1_000_000;
/// Heartbeat timeouts accepted (ms).
pub const HEARTBEAT_MIN_MS: u32 = 500;
pub const HEARTBEAT_MAX_MS: u32 = 600_000;
/// Pending timeouts a device may be configured with (ms; PENDING_ACK carries 16 bits).
pub const PENDING_TIMEOUT_MIN_MS: u32 = 10;
pub const PENDING_TIMEOUT_MAX_MS: u32 = 65_535;
/// With the heartbeat disabled, a controller silent this long (ms) is still released:
/// a vanished client cannot hold the camera for ever.
pub const HEARTBEAT_DISABLED_RELEASE_MS: u32 = 60_000;
/// Frame rates accepted (Hz).
pub const FRAME_RATE_MIN: f32 = 0.01;
pub const FRAME_RATE_MAX: f32 = 1000.0;

/// Identity strings and fixed facts, from the `[output.gige]` config and the camera.
#[derive(Clone, Debug, PartialEq)]
pub struct DeviceIdentity {
    pub manufacturer: String,
    pub model: String,
    pub version: String,
    pub info: String,
    pub serial: String,
    pub user_name: String,
    pub mac: [u8; 6],
    pub ip: Ipv4Addr,
}

/// What the camera is: the sensor geometry and the exposure range.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraDescription {
    pub sensor_width: u32,
    pub sensor_height: u32,
    /// The ADC's bit depth (Mono10 / Mono12 are offered when it is 10 / 12).
    pub adc_bits: u8,
    pub exposure_us: f32,
    pub exposure_min_us: f32,
    pub exposure_max_us: f32,
    /// Whether the sensor model starts in auto-exposure.
    pub auto_exposure: bool,
    /// AcquisitionFrameRate at start (Hz).
    pub frame_rate_hz: f32,
    /// The highest AcquisitionFrameRate a client may write (Hz; the XML's Max): the
    /// configured rate when it sets the renderer's rate, [`FRAME_RATE_MAX`] otherwise.
    pub frame_rate_max_hz: f32,
    /// Ground-truth channels sent as chunks with every block in chunk mode (`[output]
    /// truth`; empty: none).
    pub truth: crate::render::truth::TruthChannels,
    /// Bytes of the scene's material table, sent as a chunk with the mask (PayloadSize
    /// counts it).
    pub truth_materials_len: u32,
    /// The renderer runs at AcquisitionFrameRate (`rate` trigger mode): every frame it
    /// publishes is one the client's rate asked for, so the device lets each through
    /// (thinning them again would drop the frames a loaded machine publishes late).
    pub rate_sets_schedule: bool,
}

impl CameraDescription {
    /// Pixel formats offered: Mono8, Mono16, and Mono10/Mono12 when the ADC has that depth.
    pub fn pixel_formats(&self) -> Vec<GevPixelFormat> {
        let mut v = vec![GevPixelFormat::Mono8];
        match self.adc_bits {
            10 => v.push(GevPixelFormat::Mono10),
            12 => v.push(GevPixelFormat::Mono12),
            _ => {}
        }
        v.push(GevPixelFormat::Mono16);
        v
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AcquisitionMode {
    Continuous = 0,
    SingleFrame = 1,
}

/// The camera settings a GigE Vision client controls: what hilcam renders and sends.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraSettings {
    pub width: u32,
    pub height: u32,
    pub offset_x: u32,
    pub offset_y: u32,
    pub pixel_format: GevPixelFormat,
    pub exposure_us: f32,
    pub exposure_auto: bool,
    pub acquisition_mode: AcquisitionMode,
    /// TriggerMode On for FrameStart (source Software): a frame is sent per trigger.
    pub trigger_on: bool,
    pub frame_rate_hz: f32,
    pub chunk_mode: bool,
    /// The chunks sent in chunk mode (ChunkSelector / ChunkEnable).
    pub chunks: ChunkSet,
    /// The truth channels each block carries in chunk mode (the device's, fixed).
    pub truth: crate::render::truth::TruthChannels,
    /// Bytes of the material table sent with the mask (the device's, fixed).
    pub truth_materials_len: u32,
}

impl CameraSettings {
    pub fn initial(cam: &CameraDescription) -> Self {
        CameraSettings {
            width: cam.sensor_width,
            height: cam.sensor_height,
            offset_x: 0,
            offset_y: 0,
            pixel_format: GevPixelFormat::Mono16,
            exposure_us: cam.exposure_us,
            exposure_auto: cam.auto_exposure,
            acquisition_mode: AcquisitionMode::Continuous,
            trigger_on: false,
            frame_rate_hz: cam.frame_rate_hz,
            chunk_mode: true,
            chunks: ChunkSet::ALL,
            truth: cam.truth,
            truth_materials_len: cam.truth_materials_len,
        }
    }

    /// The region of the sensor these settings ask for (Width/Height/OffsetX/OffsetY).
    pub fn window(&self) -> Window {
        Window { x: self.offset_x, y: self.offset_y, width: self.width, height: self.height }
    }

    /// Bytes of one frame's pixels.
    pub fn image_bytes(&self) -> u64 {
        u64::from(self.width) * u64::from(self.height) * self.pixel_format.bytes_per_pixel() as u64
    }

    /// Bytes of one block (pixels, plus the enabled chunks when chunk mode is on).
    pub fn payload_size(&self) -> u64 {
        let chunks =
            super::chunk::chunks_len(self.chunks, self.truth, self.truth_materials_len, self.width, self.height);
        self.image_bytes() + if self.chunk_mode { chunks } else { 0 }
    }
}

/// Stream channel 0 as negotiated by the client.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StreamChannel {
    /// Host port; 0 = channel closed.
    pub host_port: u16,
    pub destination: Ipv4Addr,
    /// IP datagram size (IP + UDP + GVSP headers + data).
    pub packet_size: u32,
    pub do_not_fragment: bool,
    /// Delay between packets, timestamp ticks (ns).
    pub packet_delay_ticks: u32,
    /// The device's stream source port (read-only for clients).
    pub source_port: u16,
    pub config: u32,
}

/// What a successful write asks the device shell to do.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Effect {
    None,
    AcquisitionStart,
    AcquisitionStop,
    SoftwareTrigger,
    TimestampLatch,
    /// A camera setting changed (publish the new settings).
    Settings,
    /// ExposureTime / ExposureAuto changed: a setting the renderer applies when it
    /// starts its next frame (a slow write: see `device.rs`, pending acknowledge).
    Exposure,
    /// Width / Height / OffsetX / OffsetY changed: the renderer renders the new region
    /// from its next frame (a slow write, like the exposure).
    Roi,
    /// AcquisitionFrameRate changed (the device's frame-rate gate re-times).
    FrameRate,
    /// The stream channel changed (destination, packet size, delay).
    Stream,
}

/// The whole register/memory state of the device.
#[derive(Clone, Debug)]
pub struct Registers {
    pub identity: DeviceIdentity,
    pub camera: CameraDescription,
    pub settings: CameraSettings,
    pub stream: StreamChannel,
    pub ccp: u32,
    pub heartbeat_timeout_ms: u32,
    pub gvcp_config: u32,
    /// Pending timeout register (ms).
    pub pending_timeout_ms: u32,
    pub acquiring: bool,
    pub latched_timestamp: u64,
    /// Capability register value.
    pub capability: u32,
    /// DeviceUserID as written (bytes; read back UTF-8 safe, see [`Registers::user_id`]).
    user_id: [u8; USER_NAME_LEN as usize],
    /// TLParamsLocked.
    pub tl_params_locked: bool,
    pub chunk_selector: ChunkKind,
    /// What the newest published frame integrated (µs): ExposureTime under auto-exposure.
    pub integrated_us: Option<f32>,
    /// SCDA may be a broadcast or multicast address (`[output.gige] allow_broadcast_stream`).
    pub allow_broadcast_stream: bool,
    firmware: String,
    xml_url: String,
    xml: Vec<u8>,
}

/// Tick frequency of GVSP timestamps and the timestamp latch: 1 GHz (ns).
pub const TICK_HZ: u64 = 1_000_000_000;

impl Registers {
    /// `xml` is the file clients download (plain XML or a zip, as `xml_file_name` says).
    pub fn new(
        identity: DeviceIdentity,
        camera: CameraDescription,
        packet_size: u32,
        xml_file_name: &str,
        xml: Vec<u8>,
    ) -> Result<Self, String> {
        if xml.len() as u32 > XML_MAX {
            return Err(format!("GenICam XML is {} bytes, device memory holds {XML_MAX}", xml.len()));
        }
        check_packet_size(packet_size).map_err(|_| {
            format!(
                "[output.gige] packet_size {packet_size}: {PACKET_SIZE_MIN}..={PACKET_SIZE_MAX} in steps of {PACKET_SIZE_INC}"
            )
        })?;
        let xml_url = format!("Local:{xml_file_name};{XML_BASE:x};{:x}", xml.len());
        let settings = CameraSettings::initial(&camera);
        let mut user_id = [0u8; USER_NAME_LEN as usize];
        let name = identity.user_name.as_bytes();
        if name.len() >= user_id.len() {
            return Err(format!(
                "[output.gige] user_name {:?}: {} bytes, DeviceUserID holds {} (UTF-8)",
                identity.user_name,
                name.len(),
                USER_NAME_LEN - 1
            ));
        }
        user_id[..name.len()].copy_from_slice(name);
        let firmware = format!("hilcam {}", identity.version);
        Ok(Registers {
            identity,
            camera,
            settings,
            stream: StreamChannel {
                host_port: 0,
                destination: Ipv4Addr::UNSPECIFIED,
                packet_size,
                do_not_fragment: false,
                packet_delay_ticks: 0,
                source_port: 0,
                config: 0,
            },
            ccp: 0,
            heartbeat_timeout_ms: 3000,
            gvcp_config: 0,
            pending_timeout_ms: 1000,
            acquiring: false,
            latched_timestamp: 0,
            capability: capability::CONCATENATION
                | capability::WRITE_MEMORY
                | capability::PACKET_RESEND
                | capability::PENDING_ACK
                | capability::HEARTBEAT_DISABLE
                | capability::SERIAL_NUMBER,
            user_id,
            tl_params_locked: false,
            chunk_selector: ChunkKind::Timestamp,
            integrated_us: None,
            allow_broadcast_stream: false,
            firmware,
            xml_url,
            xml,
        })
    }

    pub fn xml_url(&self) -> &str {
        &self.xml_url
    }

    pub fn heartbeat_disabled(&self) -> bool {
        self.gvcp_config & GVCP_CONFIG_HEARTBEAT_DISABLE != 0
    }

    pub fn pending_ack_enabled(&self) -> bool {
        self.gvcp_config & GVCP_CONFIG_PENDING_ACK_ENABLE != 0
    }

    /// DeviceUserID as text: the bytes up to the first NUL, cut back to the last whole
    /// UTF-8 character (a client that wrote more than the field holds, or a partial
    /// multi-byte character, never leaves half a character to read).
    pub fn user_id(&self) -> &str {
        let end =
            self.user_id.iter().position(|&b| b == 0).unwrap_or(self.user_id.len()).min(USER_NAME_LEN as usize - 1);
        let bytes = &self.user_id[..end];
        match std::str::from_utf8(bytes) {
            Ok(s) => s,
            Err(e) => std::str::from_utf8(&bytes[..e.valid_up_to()]).expect("valid prefix"),
        }
    }

    /// Whether the stream-shaping features (ROI, PixelFormat, chunks, packet size) are
    /// locked: while acquiring (ROI, format, chunks) or while TLParamsLocked is set (all).
    pub fn shape_locked(&self) -> bool {
        self.acquiring || self.tl_params_locked
    }

    /// The register written at `addr` belongs to stream channel 0 (only the controller
    /// writes it: see `control.rs`).
    pub fn is_stream_channel(addr: u32) -> bool {
        matches!(addr, SCP0 | SCPS0 | SCPD0 | SCDA0 | SCCFG0)
    }

    /// ExposureTime as read: the manual time, or under auto-exposure what the newest
    /// frame integrated (the configured time until one is published).
    pub fn exposure_time_us(&self) -> f32 {
        let s = &self.settings;
        if s.exposure_auto { self.integrated_us.unwrap_or(s.exposure_us) } else { s.exposure_us }
    }

    /// Whether SCDA may be `ip`: a unicast address, or anything with
    /// `allow_broadcast_stream` (0.0.0.0 closes the channel).
    fn destination_allowed(&self, ip: Ipv4Addr) -> bool {
        let mask = self.read_u32(CURRENT_SUBNET).unwrap_or(0);
        let directed = u32::from(self.identity.ip) | !mask;
        let group = ip.is_multicast() || ip.is_broadcast() || u32::from(ip) == directed;
        !group || self.allow_broadcast_stream
    }
    /// One 32-bit register.
    pub fn read_u32(&self, addr: u32) -> Result<u32, Status> {
        if !addr.is_multiple_of(4) {
            return Err(Status::BadAlignment);
        }
        let s = &self.settings;
        let v = match addr {
            VERSION => 0x0002_0000,
            DEVICE_MODE => 0x8000_0001, // big-endian registers, transmitter, UTF-8
            MAC_HIGH => u32::from(u16::from_be_bytes([self.identity.mac[0], self.identity.mac[1]])),
            MAC_LOW => u32::from_be_bytes(self.identity.mac[2..6].try_into().expect("4 bytes")),
            IP_CONFIG_SUPPORTED => 0x0000_0007,
            IP_CONFIG_CURRENT => 0x0000_0005,
            CURRENT_IP => u32::from(self.identity.ip),
            CURRENT_SUBNET => {
                if self.identity.ip.is_loopback() {
                    0xFF00_0000
                } else {
                    0xFFFF_FF00
                }
            }
            N_INTERFACES => 1,
            N_MESSAGE_CHANNELS => 0,
            N_STREAM_CHANNELS => 1,
            GVCP_CAPABILITY => self.capability,
            HEARTBEAT_TIMEOUT => self.heartbeat_timeout_ms,
            TICK_FREQ_HIGH => (TICK_HZ >> 32) as u32,
            TICK_FREQ_LOW => TICK_HZ as u32,
            TIMESTAMP_CONTROL => 0,
            TIMESTAMP_VALUE_HIGH => (self.latched_timestamp >> 32) as u32,
            TIMESTAMP_VALUE_LOW => self.latched_timestamp as u32,
            GVCP_CONFIG => self.gvcp_config,
            PENDING_TIMEOUT => self.pending_timeout_ms,
            CCP => self.ccp,
            SCP0 => u32::from(self.stream.host_port),
            SCPS0 => self.stream.packet_size | if self.stream.do_not_fragment { SCPS_DO_NOT_FRAGMENT } else { 0 },
            a if (USER_NAME..USER_NAME + USER_NAME_LEN).contains(&a) => {
                let text = self.user_id().as_bytes();
                let mut w = [0u8; 4];
                for (k, b) in w.iter_mut().enumerate() {
                    *b = text.get((a - USER_NAME) as usize + k).copied().unwrap_or(0);
                }
                u32::from_be_bytes(w)
            }
            SCPD0 => self.stream.packet_delay_ticks,
            SCDA0 => u32::from(self.stream.destination),
            SCSP0 => u32::from(self.stream.source_port),
            SCC0 => 0,
            SCCFG0 => self.stream.config,
            a if a < BOOTSTRAP_END => return Ok(self.read_bytes_word(a)),
            a if (XML_BASE..XML_BASE + XML_MAX).contains(&a) => {
                let i = (a - XML_BASE) as usize;
                let mut w = [0u8; 4];
                for (k, b) in w.iter_mut().enumerate() {
                    *b = self.xml.get(i + k).copied().unwrap_or(0);
                }
                u32::from_be_bytes(w)
            }
            WIDTH => s.width,
            HEIGHT => s.height,
            OFFSET_X => s.offset_x,
            OFFSET_Y => s.offset_y,
            SENSOR_WIDTH => self.camera.sensor_width,
            SENSOR_HEIGHT => self.camera.sensor_height,
            PIXEL_FORMAT => s.pixel_format.pfnc(),
            PAYLOAD_SIZE => s.payload_size().min(u64::from(u32::MAX)) as u32,
            ACQUISITION_MODE => s.acquisition_mode as u32,
            ACQUISITION_START | ACQUISITION_STOP | TRIGGER_SOFTWARE => 0,
            TRIGGER_SELECTOR | TRIGGER_SOURCE => 0,
            TRIGGER_MODE => u32::from(s.trigger_on),
            EXPOSURE_TIME => self.exposure_time_us().to_bits(),
            EXPOSURE_AUTO => u32::from(s.exposure_auto) * 2, // Off = 0, Continuous = 2
            FRAME_RATE => s.frame_rate_hz.to_bits(),
            CHUNK_MODE_ACTIVE => u32::from(s.chunk_mode),
            ACQUISITION_STATUS => u32::from(self.acquiring),
            WIDTH_MAX => self.camera.sensor_width - s.offset_x,
            HEIGHT_MAX => self.camera.sensor_height - s.offset_y,
            EXPOSURE_MODE => 1,
            TL_PARAMS_LOCKED => u32::from(self.tl_params_locked),
            CHUNK_SELECTOR => self.chunk_selector as u32,
            CHUNK_ENABLE => u32::from(s.chunks.contains(self.chunk_selector)),
            a if (FIRMWARE_VERSION..FEATURES_END).contains(&a) => {
                let mut w = [0u8; 4];
                for (k, b) in w.iter_mut().enumerate() {
                    let i = (a - FIRMWARE_VERSION) as usize + k;
                    // NUL-terminated: the last byte stays 0.
                    if i + 1 < FIRMWARE_VERSION_LEN as usize {
                        *b = self.firmware.as_bytes().get(i).copied().unwrap_or(0);
                    }
                }
                u32::from_be_bytes(w)
            }
            _ => return Err(Status::InvalidAddress),
        };
        Ok(v)
    }

    /// Bootstrap words made of string bytes (names, URLs), 0 elsewhere.
    fn read_bytes_word(&self, addr: u32) -> u32 {
        let mut w = [0u8; 4];
        for (k, b) in w.iter_mut().enumerate() {
            *b = self.bootstrap_byte(addr + k as u32);
        }
        u32::from_be_bytes(w)
    }

    fn bootstrap_byte(&self, a: u32) -> u8 {
        let field = |base: u32, len: u32, s: &str| -> Option<u8> {
            if (base..base + len).contains(&a) {
                // NUL-terminated: the last byte of the field is always 0.
                let i = (a - base) as usize;
                Some(if i + 1 < len as usize { s.as_bytes().get(i).copied().unwrap_or(0) } else { 0 })
            } else {
                None
            }
        };
        let id = &self.identity;
        field(MANUFACTURER_NAME, 32, &id.manufacturer)
            .or_else(|| field(MODEL_NAME, 32, &id.model))
            .or_else(|| field(DEVICE_VERSION, 32, &id.version))
            .or_else(|| field(MANUFACTURER_INFO, 48, &id.info))
            .or_else(|| field(SERIAL_NUMBER, 16, &id.serial))
            .or_else(|| field(XML_URL_0, XML_URL_LEN, &self.xml_url))
            .unwrap_or(0)
    }

    /// A block of memory (READMEM, DISCOVERY): every word must be readable.
    pub fn read_block(&self, addr: u32, len: u32) -> Result<Vec<u8>, Status> {
        if !addr.is_multiple_of(4) || !len.is_multiple_of(4) {
            return Err(Status::BadAlignment);
        }
        let mut out = Vec::with_capacity(len as usize);
        for k in (0..len).step_by(4) {
            let a = addr.checked_add(k).ok_or(Status::InvalidAddress)?;
            out.extend_from_slice(&self.read_u32(a)?.to_be_bytes());
        }
        Ok(out)
    }

    /// Write one register (the control channel has already been checked). CCP is
    /// handled by the control layer, which owns the controller's identity.
    pub fn write_u32(&mut self, addr: u32, v: u32) -> Result<Effect, Status> {
        if !addr.is_multiple_of(4) {
            return Err(Status::BadAlignment);
        }
        let locked = self.shape_locked();
        let cam = self.camera.clone();
        let s = &mut self.settings;
        let effect = match addr {
            HEARTBEAT_TIMEOUT => {
                if !(HEARTBEAT_MIN_MS..=HEARTBEAT_MAX_MS).contains(&v) {
                    return Err(Status::InvalidParameter);
                }
                self.heartbeat_timeout_ms = v;
                Effect::None
            }
            TIMESTAMP_CONTROL => {
                if v & TIMESTAMP_LATCH != 0 {
                    Effect::TimestampLatch
                } else {
                    Effect::None
                }
            }
            GVCP_CONFIG => {
                self.gvcp_config = v & (GVCP_CONFIG_HEARTBEAT_DISABLE | GVCP_CONFIG_PENDING_ACK_ENABLE);
                Effect::None
            }
            SCP0 => {
                self.stream.host_port = (v & 0xFFFF) as u16;
                Effect::Stream
            }
            SCPS0 if self.tl_params_locked => return Err(Status::WriteProtect),
            SCPS0 => {
                if v & SCPS_BIG_ENDIAN != 0 {
                    return Err(Status::InvalidParameter);
                }
                let size = v & 0xFFFF;
                check_packet_size(size)?;
                self.stream.packet_size = size;
                self.stream.do_not_fragment = v & SCPS_DO_NOT_FRAGMENT != 0;
                Effect::Stream
            }
            SCPD0 => {
                if v > SCPD_MAX_TICKS {
                    return Err(Status::InvalidParameter);
                }
                self.stream.packet_delay_ticks = v;
                Effect::Stream
            }
            SCDA0 => {
                if !self.destination_allowed(Ipv4Addr::from(v)) {
                    return Err(Status::InvalidParameter);
                }
                self.stream.destination = Ipv4Addr::from(v);
                Effect::Stream
            }
            a if (USER_NAME..USER_NAME + USER_NAME_LEN).contains(&a) => {
                let i = (a - USER_NAME) as usize;
                self.user_id[i..i + 4].copy_from_slice(&v.to_be_bytes());
                Effect::None
            }
            SCCFG0 => {
                // Multipart and the other extended stream modes are not offered.
                if v != 0 {
                    return Err(Status::InvalidParameter);
                }
                self.stream.config = v;
                Effect::Stream
            }
            MCP | MCDA => Effect::None, // no message channel: accepted and ignored
            WIDTH | HEIGHT | OFFSET_X | OFFSET_Y | PIXEL_FORMAT | CHUNK_MODE_ACTIVE | CHUNK_ENABLE if locked => {
                return Err(Status::WriteProtect);
            }
            WIDTH => {
                if v == 0 || u64::from(v) + u64::from(s.offset_x) > u64::from(cam.sensor_width) {
                    return Err(Status::InvalidParameter);
                }
                s.width = v;
                Effect::Roi
            }
            HEIGHT => {
                if v == 0 || u64::from(v) + u64::from(s.offset_y) > u64::from(cam.sensor_height) {
                    return Err(Status::InvalidParameter);
                }
                s.height = v;
                Effect::Roi
            }
            OFFSET_X => {
                if u64::from(v) + u64::from(s.width) > u64::from(cam.sensor_width) {
                    return Err(Status::InvalidParameter);
                }
                s.offset_x = v;
                Effect::Roi
            }
            OFFSET_Y => {
                if u64::from(v) + u64::from(s.height) > u64::from(cam.sensor_height) {
                    return Err(Status::InvalidParameter);
                }
                s.offset_y = v;
                Effect::Roi
            }
            PIXEL_FORMAT => {
                let f = GevPixelFormat::from_pfnc(v)
                    .filter(|f| cam.pixel_formats().contains(f))
                    .ok_or(Status::InvalidParameter)?;
                s.pixel_format = f;
                Effect::Settings
            }
            CHUNK_MODE_ACTIVE => {
                s.chunk_mode = match v {
                    0 => false,
                    1 => true,
                    _ => return Err(Status::InvalidParameter),
                };
                Effect::Settings
            }
            ACQUISITION_MODE => {
                s.acquisition_mode = match v {
                    0 => AcquisitionMode::Continuous,
                    1 => AcquisitionMode::SingleFrame,
                    _ => return Err(Status::InvalidParameter),
                };
                Effect::Settings
            }
            ACQUISITION_START => {
                if v == 0 {
                    Effect::None
                } else {
                    Effect::AcquisitionStart
                }
            }
            ACQUISITION_STOP => {
                if v == 0 {
                    Effect::None
                } else {
                    Effect::AcquisitionStop
                }
            }
            TRIGGER_SELECTOR | TRIGGER_SOURCE => {
                // One selector (FrameStart) and one source (Software).
                if v != 0 {
                    return Err(Status::InvalidParameter);
                }
                Effect::None
            }
            TRIGGER_MODE => {
                s.trigger_on = match v {
                    0 => false,
                    1 => true,
                    _ => return Err(Status::InvalidParameter),
                };
                Effect::Settings
            }
            TRIGGER_SOFTWARE => {
                if v == 0 {
                    Effect::None
                } else {
                    Effect::SoftwareTrigger
                }
            }
            EXPOSURE_TIME => {
                let us = f32::from_bits(v);
                if !(us.is_finite() && (cam.exposure_min_us..=cam.exposure_max_us).contains(&us)) {
                    return Err(Status::InvalidParameter);
                }
                s.exposure_us = us;
                s.exposure_auto = false;
                Effect::Exposure
            }
            EXPOSURE_AUTO => {
                let auto = match v {
                    0 => false,
                    2 => true,
                    _ => return Err(Status::InvalidParameter),
                };
                // Auto → Off keeps integrating what the auto-exposure had chosen (SFNC).
                if s.exposure_auto && !auto {
                    let t = self.integrated_us.unwrap_or(s.exposure_us);
                    s.exposure_us = t.clamp(cam.exposure_min_us, cam.exposure_max_us);
                }
                s.exposure_auto = auto;
                Effect::Exposure
            }
            EXPOSURE_MODE => {
                if v != 1 {
                    return Err(Status::InvalidParameter);
                }
                Effect::None
            }
            TL_PARAMS_LOCKED => {
                self.tl_params_locked = match v {
                    0 => false,
                    1 => true,
                    _ => return Err(Status::InvalidParameter),
                };
                Effect::None
            }
            CHUNK_SELECTOR => {
                self.chunk_selector = ChunkKind::from_u32(v).ok_or(Status::InvalidParameter)?;
                Effect::None
            }
            CHUNK_ENABLE => {
                let on = match v {
                    0 => false,
                    1 => true,
                    _ => return Err(Status::InvalidParameter),
                };
                s.chunks = s.chunks.with(self.chunk_selector, on);
                Effect::Settings
            }
            FRAME_RATE => {
                let hz = f32::from_bits(v);
                if !(hz.is_finite() && (FRAME_RATE_MIN..=cam.frame_rate_max_hz).contains(&hz)) {
                    return Err(Status::InvalidParameter);
                }
                s.frame_rate_hz = hz;
                Effect::FrameRate
            }
            a if self.read_u32(a).is_ok() => return Err(Status::WriteProtect),
            _ => return Err(Status::InvalidAddress),
        };
        Ok(effect)
    }

    /// WRITEMEM: word by word; stops at the first word refused.
    pub fn write_block(&mut self, addr: u32, data: &[u8]) -> (Result<(), Status>, Vec<Effect>, u16) {
        if !addr.is_multiple_of(4) || !data.len().is_multiple_of(4) {
            return (Err(Status::BadAlignment), vec![], 0);
        }
        let mut effects = Vec::new();
        for (k, w) in data.chunks_exact(4).enumerate() {
            let a = match addr.checked_add(4 * k as u32) {
                Some(a) => a,
                None => return (Err(Status::InvalidAddress), effects, (4 * k) as u16),
            };
            match self.write_u32(a, u32::from_be_bytes(w.try_into().expect("4 bytes"))) {
                Ok(e) => effects.push(e),
                Err(st) => return (Err(st), effects, (4 * k) as u16),
            }
        }
        (Ok(()), effects, data.len() as u16)
    }
}

fn check_packet_size(size: u32) -> Result<(), Status> {
    if (PACKET_SIZE_MIN..=PACKET_SIZE_MAX).contains(&size) && size.is_multiple_of(PACKET_SIZE_INC) {
        Ok(())
    } else {
        Err(Status::InvalidParameter)
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    pub(crate) fn camera() -> CameraDescription {
        CameraDescription {
            sensor_width: 64,
            sensor_height: 48,
            adc_bits: 12,
            exposure_us: 1000.0,
            exposure_min_us: 1.0,
            exposure_max_us: 1e6,
            auto_exposure: true,
            frame_rate_hz: 10.0,
            frame_rate_max_hz: FRAME_RATE_MAX,
            truth: Default::default(),
            truth_materials_len: 0,
            rate_sets_schedule: false,
        }
    }

    pub(crate) fn registers() -> Registers {
        let id = DeviceIdentity {
            manufacturer: "hilcam".into(),
            model: "hilcam-sim".into(),
            version: "0.1.0".into(),
            info: "test".into(),
            serial: "HC0001".into(),
            user_name: "".into(),
            mac: [2, 0x48, 0x4c, 0, 0, 1],
            ip: Ipv4Addr::LOCALHOST,
        };
        Registers::new(id, camera(), 1500, "hilcam.xml", b"<xml/>".to_vec()).unwrap()
    }

    #[test]
    fn strings_and_url_read_back() {
        let r = registers();
        let model = r.read_block(MODEL_NAME, 32).unwrap();
        assert_eq!(&model[..10], b"hilcam-sim");
        assert_eq!(model[10], 0);
        let url = r.read_block(XML_URL_0, 512).unwrap();
        let end = url.iter().position(|&b| b == 0).unwrap();
        assert_eq!(std::str::from_utf8(&url[..end]).unwrap(), "Local:hilcam.xml;10000;6");
        assert_eq!(&r.read_block(XML_BASE, 8).unwrap()[..6], b"<xml/>");
    }

    #[test]
    fn roi_and_ranges_are_validated() {
        let mut r = registers();
        assert_eq!(r.write_u32(WIDTH, 65), Err(Status::InvalidParameter));
        assert_eq!(r.write_u32(WIDTH, 32), Ok(Effect::Roi));
        assert_eq!(r.write_u32(OFFSET_X, 32), Ok(Effect::Roi));
        assert_eq!(r.write_u32(OFFSET_X, 33), Err(Status::InvalidParameter));
        assert_eq!(r.write_u32(WIDTH, 33), Err(Status::InvalidParameter));
        assert_eq!(r.write_u32(PIXEL_FORMAT, GevPixelFormat::Mono10.pfnc()), Err(Status::InvalidParameter));
        assert_eq!(r.write_u32(PIXEL_FORMAT, GevPixelFormat::Mono12.pfnc()), Ok(Effect::Settings));
        assert_eq!(r.read_u32(PAYLOAD_SIZE).unwrap() as u64, 32 * 48 * 2 + super::super::chunk::CHUNK_OVERHEAD as u64);
        assert_eq!(r.write_u32(EXPOSURE_TIME, 0.5f32.to_bits()), Err(Status::InvalidParameter));
        assert_eq!(r.write_u32(EXPOSURE_TIME, f32::NAN.to_bits()), Err(Status::InvalidParameter));
        assert!(r.settings.exposure_auto);
        assert_eq!(r.write_u32(EXPOSURE_TIME, 250.0f32.to_bits()), Ok(Effect::Exposure));
        assert!(!r.settings.exposure_auto, "writing ExposureTime turns auto-exposure off");
        assert_eq!(r.write_u32(SENSOR_WIDTH, 1), Err(Status::WriteProtect));
        assert_eq!(r.write_u32(0x3_0000, 1), Err(Status::InvalidAddress));
        assert_eq!(r.read_u32(WIDTH + 1), Err(Status::BadAlignment));
        assert_eq!(r.write_u32(SCPS0, 100), Err(Status::InvalidParameter));
        assert_eq!(r.write_u32(SCPS0, 8192), Ok(Effect::Stream));
    }

    #[test]
    fn the_frame_rate_is_bounded_by_the_cameras_maximum() {
        let mut r = registers();
        assert_eq!(r.write_u32(FRAME_RATE, 500.0f32.to_bits()), Ok(Effect::FrameRate));
        let cam = CameraDescription { frame_rate_max_hz: 20.0, ..camera() };
        r.camera = cam;
        assert_eq!(r.write_u32(FRAME_RATE, 20.0f32.to_bits()), Ok(Effect::FrameRate));
        assert_eq!(r.write_u32(FRAME_RATE, 20.5f32.to_bits()), Err(Status::InvalidParameter));
        assert_eq!(r.write_u32(FRAME_RATE, 0.001f32.to_bits()), Err(Status::InvalidParameter));
        assert_eq!(r.settings.frame_rate_hz, 20.0, "a refused write keeps the rate");
    }

    /// Issue 37, defect 1: SCPD 0xFFFFFFFF (4.3 s per packet) froze the stream.
    #[test]
    fn the_packet_delay_is_bounded() {
        let mut r = registers();
        assert_eq!(r.write_u32(SCPD0, u32::MAX), Err(Status::InvalidParameter));
        assert_eq!(r.write_u32(SCPD0, SCPD_MAX_TICKS + 1), Err(Status::InvalidParameter));
        assert_eq!(r.read_u32(SCPD0), Ok(0), "a refused delay is not stored");
        assert_eq!(r.write_u32(SCPD0, SCPD_MAX_TICKS), Ok(Effect::Stream));
    }

    /// Issue 37, defect 7: SCDA accepted broadcast and multicast destinations.
    #[test]
    fn the_stream_goes_to_one_host_unless_allowed() {
        let mut r = registers();
        for group in [Ipv4Addr::BROADCAST, Ipv4Addr::new(127, 255, 255, 255), Ipv4Addr::new(239, 1, 2, 3)] {
            assert_eq!(r.write_u32(SCDA0, u32::from(group)), Err(Status::InvalidParameter), "{group}");
        }
        assert_eq!(r.write_u32(SCDA0, u32::from(Ipv4Addr::new(127, 0, 0, 9))), Ok(Effect::Stream));
        assert_eq!(r.write_u32(SCDA0, 0), Ok(Effect::Stream), "0.0.0.0 closes the channel");
        r.allow_broadcast_stream = true;
        assert_eq!(r.write_u32(SCDA0, u32::from(Ipv4Addr::new(239, 1, 2, 3))), Ok(Effect::Stream));
    }

    /// Issue 37, defect 6: a multi-byte DeviceUserID was cut mid-character.
    #[test]
    fn device_user_id_is_read_back_whole_characters_only() {
        let mut r = registers();
        let read = |r: &Registers| {
            let b = r.read_block(USER_NAME, USER_NAME_LEN).unwrap();
            let end = b.iter().position(|&c| c == 0).unwrap_or(b.len());
            String::from_utf8(b[..end].to_vec()).expect("valid UTF-8")
        };
        let mut write = |text: &[u8]| {
            let mut field = [0u8; USER_NAME_LEN as usize];
            field[..text.len()].copy_from_slice(text);
            for (k, w) in field.chunks_exact(4).enumerate() {
                r.write_u32(USER_NAME + 4 * k as u32, u32::from_be_bytes(w.try_into().unwrap())).unwrap();
            }
            read(&r)
        };
        assert_eq!(write("Kamera äöü".as_bytes()), "Kamera äöü");
        // 16 bytes of two-byte characters, no room for the NUL: 7 whole characters.
        assert_eq!(write("ÄÖÜßäöüé".as_bytes()), "ÄÖÜßäöü");
        // A client that cut a 3-byte character itself: the partial bytes are not shown.
        let cut = &"ab€".as_bytes()[..4];
        assert_eq!(write(cut), "ab");
        assert_eq!(r.user_id(), "ab");
        // The bootstrap block a DISCOVERY_ACK carries shows the same.
        assert_eq!(&r.read_block(0, DISCOVERY_LEN).unwrap()[USER_NAME as usize..][..3], b"ab\0");
    }

    #[test]
    fn width_max_and_the_width_range_follow_the_offsets() {
        let mut r = registers();
        assert_eq!((r.read_u32(WIDTH_MAX), r.read_u32(HEIGHT_MAX)), (Ok(64), Ok(48)));
        assert_eq!(r.write_u32(WIDTH, 40), Ok(Effect::Roi));
        assert_eq!(r.write_u32(OFFSET_X, 24), Ok(Effect::Roi));
        assert_eq!(r.read_u32(WIDTH_MAX), Ok(40));
        assert_eq!(r.write_u32(WIDTH, 41), Err(Status::InvalidParameter), "beyond WidthMax");
        assert_eq!(r.write_u32(OFFSET_Y, 8), Err(Status::InvalidParameter), "Height 48 leaves no room");
        assert_eq!(r.write_u32(HEIGHT, 40), Ok(Effect::Roi));
        assert_eq!(r.write_u32(OFFSET_Y, 8), Ok(Effect::Roi));
        assert_eq!(r.read_u32(HEIGHT_MAX), Ok(40));
        assert_eq!(r.write_u32(WIDTH_MAX, 64), Err(Status::WriteProtect));
    }

    /// Issue 37: ExposureTime read 50 µs while auto-exposure integrated 26 µs, and kept
    /// the last manual value after ExposureAuto went back to Continuous.
    #[test]
    fn exposure_time_reads_what_the_sensor_integrates() {
        let mut r = registers();
        let read = |r: &Registers| f32::from_bits(r.read_u32(EXPOSURE_TIME).unwrap());
        assert!(r.settings.exposure_auto);
        assert_eq!(read(&r), 1000.0, "no frame yet: the configured time");
        r.integrated_us = Some(26.0);
        assert_eq!(read(&r), 26.0, "auto: what the newest frame integrated");
        assert_eq!(r.write_u32(EXPOSURE_TIME, 50.0f32.to_bits()), Ok(Effect::Exposure));
        assert_eq!(read(&r), 50.0, "manual");
        assert_eq!(r.write_u32(EXPOSURE_AUTO, 2), Ok(Effect::Exposure));
        r.integrated_us = Some(31.0);
        assert_eq!(read(&r), 31.0, "back to Continuous: the auto-exposure's time, not the last manual one");
        assert_eq!(r.write_u32(EXPOSURE_AUTO, 0), Ok(Effect::Exposure));
        assert_eq!(read(&r), 31.0, "auto → Off keeps integrating what it had chosen");
        assert!(!r.settings.exposure_auto);
        assert_eq!((r.read_u32(EXPOSURE_MODE), r.write_u32(EXPOSURE_MODE, 1)), (Ok(1), Ok(Effect::None)));
        assert_eq!(r.write_u32(EXPOSURE_MODE, 2), Err(Status::InvalidParameter), "Timed only");
    }

    #[test]
    fn tl_params_locked_freezes_the_stream_shape_and_chunks_switch_one_by_one() {
        let mut r = registers();
        let full = r.read_u32(PAYLOAD_SIZE).unwrap();
        assert_eq!(r.write_u32(CHUNK_SELECTOR, ChunkKind::FrameId as u32), Ok(Effect::None));
        assert_eq!(r.read_u32(CHUNK_ENABLE), Ok(1));
        assert_eq!(r.write_u32(CHUNK_ENABLE, 0), Ok(Effect::Settings));
        assert_eq!(r.read_u32(CHUNK_ENABLE), Ok(0));
        assert_eq!(r.read_u32(PAYLOAD_SIZE).unwrap(), full - 16, "the FrameID chunk's 16 bytes");
        assert_eq!(r.write_u32(CHUNK_SELECTOR, 9), Err(Status::InvalidParameter));
        assert_eq!(r.write_u32(TL_PARAMS_LOCKED, 1), Ok(Effect::None));
        for (a, v) in [(WIDTH, 16), (PIXEL_FORMAT, GevPixelFormat::Mono8.pfnc()), (CHUNK_ENABLE, 1), (SCPS0, 1000)] {
            assert_eq!(r.write_u32(a, v), Err(Status::WriteProtect), "{a:#x}");
        }
        assert_eq!(r.write_u32(EXPOSURE_TIME, 20.0f32.to_bits()), Ok(Effect::Exposure), "not a stream shape");
        assert_eq!(r.write_u32(TL_PARAMS_LOCKED, 0), Ok(Effect::None));
        assert_eq!(r.write_u32(WIDTH, 16), Ok(Effect::Roi));
    }

    #[test]
    fn firmware_version_is_a_terminated_string() {
        let r = registers();
        let b = r.read_block(FIRMWARE_VERSION, FIRMWARE_VERSION_LEN).unwrap();
        assert_eq!(&b[..13], b"hilcam 0.1.0\0");
    }

    #[test]
    fn geometry_is_locked_while_acquiring() {
        let mut r = registers();
        r.acquiring = true;
        assert_eq!(r.write_u32(WIDTH, 16), Err(Status::WriteProtect));
        assert_eq!(r.write_u32(EXPOSURE_TIME, 10.0f32.to_bits()), Ok(Effect::Exposure));
    }
}
