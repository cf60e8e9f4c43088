//! The GenICam XML that describes the camera to a GigE Vision client: standard
//! (SFNC) feature names over the registers of `registers.rs`, ranges from the camera
//! description. Pure text generation; the device serves it from memory at
//! [`registers::XML_BASE`](super::registers::XML_BASE).

use super::chunk::{self, ChunkKind, META_CHUNK_ID};
use super::registers::{self as reg, CameraDescription, DeviceIdentity};
use std::fmt::Write;

/// Register access of a generated node.
#[derive(Clone, Copy)]
enum Access {
    Ro,
    Rw,
    Wo,
}

impl Access {
    fn as_str(self) -> &'static str {
        match self {
            Access::Ro => "RO",
            Access::Rw => "RW",
            Access::Wo => "WO",
        }
    }
}

fn int_reg(x: &mut String, name: &str, address: u32, len: u32, access: Access, port: &str) {
    let _ = writeln!(
        x,
        "<IntReg Name=\"{name}\"><Address>{address:#x}</Address><Length>{len}</Length>\
         <AccessMode>{}</AccessMode><pPort>{port}</pPort><Cachable>NoCache</Cachable>\
         <Sign>Unsigned</Sign><Endianess>BigEndian</Endianess></IntReg>",
        access.as_str()
    );
}

/// An Integer feature over its own register, with a range.
fn integer(x: &mut String, name: &str, address: u32, access: Access, min: u64, max: u64, inc: u64) {
    integer_with(x, name, address, access, "", &format!("<Min>{min}</Min><Max>{max}</Max><Inc>{inc}</Inc>"));
}

/// An Integer over its own register; `locked`: a `<pIsLocked>` node (or ""), `range`:
/// its Min/pMin, Max/pMax, Inc elements.
fn integer_with(x: &mut String, name: &str, address: u32, access: Access, locked: &str, range: &str) {
    let _ = writeln!(
        x,
        "<Integer Name=\"{name}\" NameSpace=\"Standard\">{}<pValue>{name}Reg</pValue>{range}</Integer>",
        is_locked(locked)
    );
    int_reg(x, &format!("{name}Reg"), address, 4, access, "Device");
}

/// `<pIsLocked>` of a feature that TLParamsLocked freezes.
fn is_locked(node: &str) -> String {
    if node.is_empty() { String::new() } else { format!("<pIsLocked>{node}</pIsLocked>") }
}

/// Features TLParamsLocked makes read-only (the device refuses their writes too).
const LOCKED_BY: &str = "TLParamsLocked";

fn float(x: &mut String, name: &str, address: u32, min: f32, max: f32, unit: &str) {
    let _ = write!(
        x,
        "<Float Name=\"{name}\" NameSpace=\"Standard\"><pValue>{name}Reg</pValue>\
         <Min>{min}</Min><Max>{max}</Max><Unit>{unit}</Unit></Float>\n\
         <FloatReg Name=\"{name}Reg\"><Address>{address:#x}</Address><Length>4</Length>\
         <AccessMode>RW</AccessMode><pPort>Device</pPort><Cachable>NoCache</Cachable>\
         <Endianess>BigEndian</Endianess></FloatReg>\n"
    );
}

fn enumeration(x: &mut String, name: &str, address: u32, entries: &[(&str, u32)]) {
    enumeration_with(x, name, address, "", "", entries);
}

/// An Enumeration with optional `<pIsLocked>` and `<pSelected>` nodes.
fn enumeration_with(x: &mut String, name: &str, address: u32, locked: &str, selected: &str, entries: &[(&str, u32)]) {
    // Element order is the GenApi schema's: pIsLocked, the entries, pValue, pSelected.
    let _ = write!(x, "<Enumeration Name=\"{name}\" NameSpace=\"Standard\">{}", is_locked(locked));
    for (entry, value) in entries {
        let _ = write!(x, "<EnumEntry Name=\"{entry}\"><Value>{value}</Value></EnumEntry>");
    }
    let _ = write!(x, "<pValue>{name}Reg</pValue>");
    if !selected.is_empty() {
        let _ = write!(x, "<pSelected>{selected}</pSelected>");
    }
    let _ = writeln!(x, "</Enumeration>");
    int_reg(x, &format!("{name}Reg"), address, 4, Access::Rw, "Device");
}

fn command(x: &mut String, name: &str, address: u32, value: u32) {
    let _ = writeln!(
        x,
        "<Command Name=\"{name}\" NameSpace=\"Standard\"><pValue>{name}Reg</pValue>\
         <CommandValue>{value}</CommandValue></Command>"
    );
    int_reg(x, &format!("{name}Reg"), address, 4, Access::Wo, "Device");
}

fn string_reg(x: &mut String, name: &str, address: u32, len: u32, access: Access) {
    let _ = writeln!(
        x,
        "<StringReg Name=\"{name}\" NameSpace=\"Standard\"><Address>{address:#x}</Address>\
         <Length>{len}</Length><AccessMode>{}</AccessMode><pPort>Device</pPort><Cachable>NoCache</Cachable></StringReg>",
        access.as_str()
    );
}

/// A Boolean (0 / 1) over its own register.
fn boolean(x: &mut String, name: &str, address: u32, locked: &str) {
    let _ = writeln!(
        x,
        "<Boolean Name=\"{name}\" NameSpace=\"Standard\">{}<pValue>{name}Reg</pValue>\
         <OnValue>1</OnValue><OffValue>0</OffValue></Boolean>",
        is_locked(locked)
    );
    int_reg(x, &format!("{name}Reg"), address, 4, Access::Rw, "Device");
}

/// An SFNC chunk feature: 8 bytes at the start of chunk `id`'s data.
fn chunk_feature(x: &mut String, name: &str, id: u32, float: bool) {
    let port = format!("{name}Port");
    let _ = writeln!(x, "<Port Name=\"{port}\"><ChunkID>{id:08X}</ChunkID></Port>");
    if float {
        let _ = writeln!(
            x,
            "<Float Name=\"{name}\" NameSpace=\"Standard\"><pValue>{name}Reg</pValue><Unit>us</Unit></Float>\
             <FloatReg Name=\"{name}Reg\"><Address>0x0</Address><Length>8</Length><AccessMode>RO</AccessMode>\
             <pPort>{port}</pPort><Cachable>NoCache</Cachable><Endianess>BigEndian</Endianess></FloatReg>"
        );
    } else {
        let _ = writeln!(x, "<Integer Name=\"{name}\" NameSpace=\"Standard\"><pValue>{name}Reg</pValue></Integer>");
        int_reg(x, &format!("{name}Reg"), 0, 8, Access::Ro, &port);
    }
}

fn category(x: &mut String, name: &str, features: &[&str]) {
    let _ = write!(x, "<Category Name=\"{name}\" NameSpace=\"Standard\">");
    for f in features {
        let _ = write!(x, "<pFeature>{f}</pFeature>");
    }
    let _ = writeln!(x, "</Category>");
}

/// Chunk features: the metadata chunk's fields (offsets from `chunk.rs`).
const CHUNK_FIELDS: [(&str, u32, u32); 7] = [
    ("ChunkFrameSequence", 0, 8),
    ("ChunkPoseSequence", 8, 4),
    ("ChunkFlags", 12, 4),
    ("ChunkPoseTime", 16, 8),
    ("ChunkPoseArrival", 24, 8),
    ("ChunkSamplesPerPixelMilli", 40, 4),
    ("ChunkExposureTimeNs", 48, 8),
];

/// The whole XML file.
pub fn xml(id: &DeviceIdentity, cam: &CameraDescription) -> String {
    let mut x = String::with_capacity(16 * 1024);
    let _ = writeln!(x, "<?xml version=\"1.0\" encoding=\"utf-8\"?>");
    let _ = writeln!(
        x,
        "<RegisterDescription ModelName=\"{}\" VendorName=\"{}\" ToolTip=\"hilcam: a simulated camera\" \
         StandardNameSpace=\"GEV\" SchemaMajorVersion=\"1\" SchemaMinorVersion=\"1\" SchemaSubMinorVersion=\"0\" \
         MajorVersion=\"1\" MinorVersion=\"0\" SubMinorVersion=\"0\" \
         ProductGuid=\"6a1c6b4e-5c2d-4d8a-9d54-68696c63616d\" VersionGuid=\"6a1c6b4e-5c2d-4d8a-9d54-000000000001\" \
         xmlns=\"http://www.genicam.org/GenApi/Version_1_1\" \
         xmlns:xsi=\"http://www.w3.org/2001/XMLSchema-instance\" \
         xsi:schemaLocation=\"http://www.genicam.org/GenApi/Version_1_1 http://www.genicam.org/GenApi/GenApiSchema_Version_1_1.xsd\">",
        xml_escape(&id.model),
        xml_escape(&id.manufacturer)
    );
    categories(&mut x);
    device_features(&mut x);
    image_format_features(&mut x, cam);
    acquisition_features(&mut x, cam);
    transport_features(&mut x);
    chunk_features(&mut x, cam);
    let _ = writeln!(x, "<Port Name=\"Device\" NameSpace=\"Standard\"/>");
    let _ = writeln!(x, "</RegisterDescription>");
    x
}

/// The categories a client's feature tree shows, Root first.
fn categories(x: &mut String) {
    category(
        x,
        "Root",
        &["DeviceControl", "ImageFormatControl", "AcquisitionControl", "TransportLayerControl", "ChunkDataControl"],
    );
    category(
        x,
        "DeviceControl",
        &[
            "DeviceVendorName",
            "DeviceModelName",
            "DeviceVersion",
            "DeviceFirmwareVersion",
            "DeviceSerialNumber",
            "DeviceUserID",
        ],
    );
    category(
        x,
        "ImageFormatControl",
        &[
            "SensorWidth",
            "SensorHeight",
            "WidthMax",
            "HeightMax",
            "Width",
            "Height",
            "OffsetX",
            "OffsetY",
            "PixelFormat",
        ],
    );
    category(
        x,
        "AcquisitionControl",
        &[
            "AcquisitionMode",
            "AcquisitionStart",
            "AcquisitionStop",
            "AcquisitionFrameRate",
            "TriggerSelector",
            "TriggerMode",
            "TriggerSource",
            "TriggerSoftware",
            "ExposureMode",
            "ExposureTime",
            "ExposureAuto",
        ],
    );
    category(
        x,
        "TransportLayerControl",
        &[
            "PayloadSize",
            "GevTimestampTickFrequency",
            "GevTimestampControlLatch",
            "GevTimestampValue",
            "GevSCPSPacketSize",
            "GevSCPD",
            "GevHeartbeatTimeout",
            "GevGVCPPendingAck",
            "GevGVCPPendingTimeout",
            "TLParamsLocked",
        ],
    );
    let mut chunk_features =
        vec!["ChunkModeActive", "ChunkSelector", "ChunkEnable", "ChunkTimestamp", "ChunkExposureTime", "ChunkFrameID"];
    chunk_features.extend(CHUNK_FIELDS.iter().map(|f| f.0));
    category(x, "ChunkDataControl", &chunk_features);
}

/// DeviceControl: the identity strings.
fn device_features(x: &mut String) {
    string_reg(x, "DeviceVendorName", reg::MANUFACTURER_NAME, 32, Access::Ro);
    string_reg(x, "DeviceModelName", reg::MODEL_NAME, 32, Access::Ro);
    string_reg(x, "DeviceVersion", reg::DEVICE_VERSION, 32, Access::Ro);
    string_reg(x, "DeviceFirmwareVersion", reg::FIRMWARE_VERSION, reg::FIRMWARE_VERSION_LEN, Access::Ro);
    string_reg(x, "DeviceSerialNumber", reg::SERIAL_NUMBER, 16, Access::Ro);
    string_reg(x, "DeviceUserID", reg::USER_NAME, reg::USER_NAME_LEN, Access::Rw);
}

/// ImageFormatControl: the sensor, the region of interest (its ranges follow each other)
/// and the pixel formats.
fn image_format_features(x: &mut String, cam: &CameraDescription) {
    let (sw, sh) = (u64::from(cam.sensor_width), u64::from(cam.sensor_height));
    integer(x, "SensorWidth", reg::SENSOR_WIDTH, Access::Ro, sw, sw, 1);
    integer(x, "SensorHeight", reg::SENSOR_HEIGHT, Access::Ro, sh, sh, 1);
    integer(x, "WidthMax", reg::WIDTH_MAX, Access::Ro, 1, sw, 1);
    integer(x, "HeightMax", reg::HEIGHT_MAX, Access::Ro, 1, sh, 1);
    // The ranges follow the region: Width ≤ SensorWidth − OffsetX (WidthMax),
    // OffsetX ≤ SensorWidth − Width.
    integer_with(x, "Width", reg::WIDTH, Access::Rw, LOCKED_BY, "<Min>1</Min><pMax>WidthMax</pMax><Inc>1</Inc>");
    integer_with(x, "Height", reg::HEIGHT, Access::Rw, LOCKED_BY, "<Min>1</Min><pMax>HeightMax</pMax><Inc>1</Inc>");
    for (offset, address, sensor, size) in
        [("OffsetX", reg::OFFSET_X, "SensorWidth", "Width"), ("OffsetY", reg::OFFSET_Y, "SensorHeight", "Height")]
    {
        let range = format!("<Min>0</Min><pMax>{offset}Max</pMax><Inc>1</Inc>");
        integer_with(x, offset, address, Access::Rw, LOCKED_BY, &range);
        let _ = writeln!(
            x,
            "<IntSwissKnife Name=\"{offset}Max\"><pVariable Name=\"S\">{sensor}</pVariable>\
             <pVariable Name=\"W\">{size}</pVariable><Formula>S-W</Formula></IntSwissKnife>"
        );
    }
    let formats: Vec<(&str, u32)> = cam.pixel_formats().iter().map(|f| (f.name(), f.pfnc())).collect();
    enumeration_with(x, "PixelFormat", reg::PIXEL_FORMAT, LOCKED_BY, "", &formats);
    integer(x, "PayloadSize", reg::PAYLOAD_SIZE, Access::Ro, 0, u64::from(u32::MAX), 1);
}

/// AcquisitionControl: start and stop, the frame rate, the software trigger, exposure.
fn acquisition_features(x: &mut String, cam: &CameraDescription) {
    enumeration(x, "AcquisitionMode", reg::ACQUISITION_MODE, &[("Continuous", 0), ("SingleFrame", 1)]);
    command(x, "AcquisitionStart", reg::ACQUISITION_START, 1);
    command(x, "AcquisitionStop", reg::ACQUISITION_STOP, 1);
    float(x, "AcquisitionFrameRate", reg::FRAME_RATE, reg::FRAME_RATE_MIN, cam.frame_rate_max_hz, "Hz");
    enumeration(x, "TriggerSelector", reg::TRIGGER_SELECTOR, &[("FrameStart", 0)]);
    enumeration(x, "TriggerMode", reg::TRIGGER_MODE, &[("Off", 0), ("On", 1)]);
    enumeration(x, "TriggerSource", reg::TRIGGER_SOURCE, &[("Software", 0)]);
    command(x, "TriggerSoftware", reg::TRIGGER_SOFTWARE, 1);
    enumeration(x, "ExposureMode", reg::EXPOSURE_MODE, &[("Timed", 1)]);
    float(x, "ExposureTime", reg::EXPOSURE_TIME, cam.exposure_min_us, cam.exposure_max_us, "us");
    enumeration(x, "ExposureAuto", reg::EXPOSURE_AUTO, &[("Off", 0), ("Continuous", 2)]);
}

/// TransportLayerControl: the GigE Vision bootstrap registers a client tunes.
fn transport_features(x: &mut String) {
    let _ = writeln!(
        x,
        "<Integer Name=\"GevTimestampTickFrequency\" NameSpace=\"Standard\"><pValue>GevTimestampTickFrequencyReg</pValue></Integer>"
    );
    int_reg(x, "GevTimestampTickFrequencyReg", reg::TICK_FREQ_HIGH, 8, Access::Ro, "Device");
    command(x, "GevTimestampControlLatch", reg::TIMESTAMP_CONTROL, reg::TIMESTAMP_LATCH);
    let _ = writeln!(
        x,
        "<Integer Name=\"GevTimestampValue\" NameSpace=\"Standard\"><pValue>GevTimestampValueReg</pValue></Integer>"
    );
    int_reg(x, "GevTimestampValueReg", reg::TIMESTAMP_VALUE_HIGH, 8, Access::Ro, "Device");
    let _ = writeln!(
        x,
        "<Integer Name=\"GevSCPSPacketSize\" NameSpace=\"Standard\"><pIsLocked>{LOCKED_BY}</pIsLocked>\
         <pValue>GevSCPSPacketSizeReg</pValue><Min>{}</Min><Max>{}</Max><Inc>{}</Inc></Integer>\n\
         <MaskedIntReg Name=\"GevSCPSPacketSizeReg\"><Address>{:#x}</Address><Length>4</Length>\
         <AccessMode>RW</AccessMode><pPort>Device</pPort><Cachable>NoCache</Cachable>\
         <LSB>31</LSB><MSB>16</MSB><Sign>Unsigned</Sign><Endianess>BigEndian</Endianess></MaskedIntReg>",
        reg::PACKET_SIZE_MIN,
        reg::PACKET_SIZE_MAX,
        reg::PACKET_SIZE_INC,
        reg::SCPS0
    );
    integer(x, "GevSCPD", reg::SCPD0, Access::Rw, 0, u64::from(reg::SCPD_MAX_TICKS), 1);
    integer(x, "TLParamsLocked", reg::TL_PARAMS_LOCKED, Access::Rw, 0, 1, 1);
    integer(
        x,
        "GevHeartbeatTimeout",
        reg::HEARTBEAT_TIMEOUT,
        Access::Rw,
        u64::from(reg::HEARTBEAT_MIN_MS),
        u64::from(reg::HEARTBEAT_MAX_MS),
        1,
    );

    // GVCP configuration bit 1 (bit 30 counted from the MSB): PENDING_ACK accepted.
    let _ = writeln!(
        x,
        "<Boolean Name=\"GevGVCPPendingAck\" NameSpace=\"Standard\"><pValue>GevGVCPPendingAckReg</pValue>\
         <OnValue>1</OnValue><OffValue>0</OffValue></Boolean>\n\
         <MaskedIntReg Name=\"GevGVCPPendingAckReg\"><Address>{:#x}</Address><Length>4</Length>\
         <AccessMode>RW</AccessMode><pPort>Device</pPort><Cachable>NoCache</Cachable>\
         <Bit>30</Bit><Endianess>BigEndian</Endianess></MaskedIntReg>",
        reg::GVCP_CONFIG
    );
    integer(x, "GevGVCPPendingTimeout", reg::PENDING_TIMEOUT, Access::Ro, 0, u64::from(u32::MAX), 1);
}

/// ChunkDataControl: which chunks a frame carries, and hilcam's metadata chunk's fields.
fn chunk_features(x: &mut String, cam: &CameraDescription) {
    boolean(x, "ChunkModeActive", reg::CHUNK_MODE_ACTIVE, LOCKED_BY);
    // ChunkEnable acts on the chunk ChunkSelector selects (the device keeps the selector).
    let kinds: Vec<ChunkKind> =
        ChunkKind::ALL.into_iter().filter(|k| *k != ChunkKind::HilcamTruth || !cam.truth.is_empty()).collect();
    let entries: Vec<(&str, u32)> = kinds.iter().map(|k| (k.name(), *k as u32)).collect();
    enumeration_with(x, "ChunkSelector", reg::CHUNK_SELECTOR, "", "ChunkEnable", &entries);
    boolean(x, "ChunkEnable", reg::CHUNK_ENABLE, LOCKED_BY);
    chunk_feature(x, "ChunkTimestamp", chunk::TIMESTAMP_CHUNK_ID, false);
    chunk_feature(x, "ChunkExposureTime", chunk::EXPOSURE_CHUNK_ID, true);
    chunk_feature(x, "ChunkFrameID", chunk::FRAME_ID_CHUNK_ID, false);
    let _ = writeln!(x, "<Port Name=\"HilcamChunkPort\"><ChunkID>{META_CHUNK_ID:08X}</ChunkID></Port>");
    for (name, offset, len) in CHUNK_FIELDS {
        let _ = writeln!(
            x,
            "<Integer Name=\"{name}\"><pValue>{name}Reg</pValue></Integer>\
             <IntReg Name=\"{name}Reg\"><Address>{offset:#x}</Address><Length>{len}</Length>\
             <AccessMode>RO</AccessMode><pPort>HilcamChunkPort</pPort><Cachable>NoCache</Cachable>\
             <Sign>Unsigned</Sign><Endianess>BigEndian</Endianess></IntReg>"
        );
    }
}

fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sink::gige::registers::tests::{camera, registers};

    #[test]
    fn xml_names_the_standard_features_and_offers_the_adc_depth() {
        let r = registers();
        let x = xml(&r.identity, &camera());
        for f in [
            "\"Width\"",
            "\"SensorHeight\"",
            "\"Mono12\"",
            "\"TriggerSoftware\"",
            "\"ExposureTime\"",
            "\"GevTimestampTickFrequency\"",
            "\"GevTimestampControlLatch\"",
            "\"AcquisitionFrameRate\"",
            "\"ChunkPoseSequence\"",
        ] {
            assert!(x.contains(f), "{f} missing");
        }
        assert!(!x.contains("Mono10"), "a 12-bit ADC offers Mono12, not Mono10");
        assert!(x.contains("<Max>64</Max>"));
        let rate =
            |x: &str| x[x.find("\"AcquisitionFrameRate\"").unwrap()..].split("</Max>").next().unwrap().to_string();
        assert!(rate(&x).ends_with("<Max>1000"), "{}", rate(&x));
        let capped = xml(&r.identity, &CameraDescription { frame_rate_max_hz: 20.0, ..camera() });
        assert!(rate(&capped).ends_with("<Max>20"), "the configured rate as the maximum: {}", rate(&capped));
        assert_eq!(x.matches("<RegisterDescription").count(), 1);
        assert!(x.trim_end().ends_with("</RegisterDescription>"));
    }
}
