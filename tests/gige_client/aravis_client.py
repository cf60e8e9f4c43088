"""A real GigE Vision client for tests/serve/gige.rs: Aravis through its GObject bindings.

Usage: aravis_client.py ADDRESS FRAMES [Feature=value ...] [--trigger] [--roi-centroid] [--sfnc]
Opens the camera at ADDRESS, writes the features, acquires FRAMES buffers (with
--trigger: TriggerMode=On, checks that nothing arrives untriggered, then one
TriggerSoftware per frame) and prints one JSON object: per buffer its status,
geometry, pixel format, leader timestamp, hilcam's metadata chunk, its truth chunks
(footprint; length and CRC-32 of each channel) and the centroid of the pixels above
half the frame's maximum. With --sfnc also the SFNC features (WidthMax, DeviceUserID,
TLParamsLocked, ChunkSelector / ChunkEnable …) and, per buffer, ChunkTimestamp,
ChunkFrameID and ChunkExposureTime through Aravis' chunk parser.
"""
import json
import struct
import sys
import zlib

import gi

gi.require_version("Aravis", "0.8")
from gi.repository import Aravis  # noqa: E402

META_CHUNK_ID = 0x48430002
FOOTPRINT_CHUNK_ID = 0x48430010
TRUTH_CHUNK_IDS = {"depth": 0x48430011, "mask": 0x48430012, "normal": 0x48430013, "body_xyz": 0x48430014}
MATERIALS_CHUNK_ID = 0x48430015


def meta(buf):
    if not buf.has_chunks():
        return None
    raw = buf.get_chunk_data(META_CHUNK_ID)
    if raw is None or len(raw) < 56:
        return None
    frame_seq, pose_seq, flags, pose_t, arrival, emit, spp_milli, depth, bits, _r, integ = struct.unpack(
        ">QIIQQQIHBBQ", bytes(raw[:56]))
    return {"frame_seq": frame_seq, "pose_seq": pose_seq, "flags": flags, "pose_t_ns": pose_t,
            "spp_milli": spp_milli, "integration_ns": integ, "bit_depth": bits}


def truth(buf):
    """hilcam's truth chunks: the footprint, and per channel present its length and CRC-32."""
    if not buf.has_chunks():
        return None
    raw = buf.get_chunk_data(FOOTPRINT_CHUNK_ID)
    if raw is None or len(raw) < 40:
        return None
    pixels, cx, cy, c0, r0, c1, r1 = struct.unpack(">QddIIII", bytes(raw[:40]))
    out = {"target_pixels": pixels, "centroid": [cx, cy] if pixels else None, "bbox": [c0, r0, c1, r1]}
    for name, cid in TRUTH_CHUNK_IDS.items():
        data = buf.get_chunk_data(cid)
        if data:  # Aravis gives empty data for a chunk id not in the block
            out[name] = {"len": len(data), "crc32": zlib.crc32(bytes(data))}
    table = buf.get_chunk_data(MATERIALS_CHUNK_ID)
    if table:  # the mask's id -> material-name table, NUL-padded
        out["materials"] = bytes(table).split(b"\0")[0].decode("ascii")
    return out


def centroid(data, w, h, bpp):
    n = w * h
    if bpp == 1:
        px = data[:n]
    else:
        px = struct.unpack("<%dH" % n, bytes(data[:2 * n]))
    mx = max(px)
    if mx == 0:
        return None, 0
    thr = mx / 2
    sx = sy = cnt = 0
    for i, v in enumerate(px):
        if v > thr:
            sx += i % w
            sy += i // w
            cnt += 1
    return [sx / cnt, sy / cnt], mx


def main():
    address, frames = sys.argv[1], int(sys.argv[2])
    trigger = "--trigger" in sys.argv
    sets = [a for a in sys.argv[3:] if "=" in a and not a.startswith("--")]
    cam = Aravis.Camera.new(address)
    cam.gv_set_stream_options(Aravis.GvStreamOption.PACKET_SOCKET_DISABLED)
    dev = cam.get_device()
    for s in sets:
        name, value = s.split("=", 1)
        node = dev.get_feature(name)
        if isinstance(node, (Aravis.GcEnumeration, Aravis.GcString)):
            dev.set_string_feature_value(name, value)
        elif isinstance(node, Aravis.GcBoolean):
            dev.set_boolean_feature_value(name, value in ("true", "1"))
        elif isinstance(node, Aravis.GcFloatNode):
            dev.set_float_feature_value(name, float(value))
        else:
            dev.set_integer_feature_value(name, int(value, 0))
    if trigger:
        dev.set_string_feature_value("TriggerSelector", "FrameStart")
        dev.set_string_feature_value("TriggerSource", "Software")
        dev.set_string_feature_value("TriggerMode", "On")
    out = {"features": {
        "Width": dev.get_integer_feature_value("Width"),
        "Height": dev.get_integer_feature_value("Height"),
        "PixelFormat": dev.get_string_feature_value("PixelFormat"),
        "ExposureTime": dev.get_float_feature_value("ExposureTime"),
        "ExposureAuto": dev.get_string_feature_value("ExposureAuto"),
        "PayloadSize": dev.get_integer_feature_value("PayloadSize"),
        "TickFrequency": dev.get_integer_feature_value("GevTimestampTickFrequency"),
    }, "buffers": []}
    if "--sfnc" in sys.argv:
        sfnc = {}
        for name in ["WidthMax", "HeightMax", "TLParamsLocked", "GevSCPD"]:
            sfnc[name] = dev.get_integer_feature_value(name)
        for name in ["DeviceUserID", "DeviceFirmwareVersion", "ExposureMode", "ChunkSelector"]:
            sfnc[name] = dev.get_string_feature_value(name)
        sfnc["ChunkModeActive"] = dev.get_boolean_feature_value("ChunkModeActive")
        enabled = {}
        for sel in ["Timestamp", "ExposureTime", "FrameID", "HilcamMetadata"]:
            dev.set_string_feature_value("ChunkSelector", sel)
            enabled[sel] = dev.get_boolean_feature_value("ChunkEnable")
        sfnc["ChunkEnable"] = enabled
        out["sfnc"] = sfnc
    parser = cam.create_chunk_parser() if "--sfnc" in sys.argv else None
    payload = cam.get_payload()
    stream = cam.create_stream(None, None)
    for _ in range(4):
        stream.push_buffer(Aravis.Buffer.new_allocate(payload))
    cam.start_acquisition()
    if trigger:
        early = stream.timeout_pop_buffer(700_000)
        out["untriggered_buffer"] = early is not None
        if early is not None:
            stream.push_buffer(early)
    for _ in range(frames):
        if trigger:
            cam.software_trigger()
        buf = stream.timeout_pop_buffer(5_000_000)
        if buf is None:
            out["buffers"].append({"status": "timeout"})
            continue
        rec = {"status": buf.get_status().value_nick, "frame_id": buf.get_frame_id(),
               "timestamp": buf.get_timestamp()}
        if buf.get_status() == Aravis.BufferStatus.SUCCESS:
            w, h = buf.get_image_width(), buf.get_image_height()
            fmt = buf.get_image_pixel_format()
            bpp = 1 if fmt == 0x01080001 else 2
            rec.update({"width": w, "height": h, "pixel_format": fmt, "meta": meta(buf), "truth": truth(buf)})
            if parser is not None:
                chunks = {}
                for name, get in [("ChunkTimestamp", parser.get_integer_value),
                                  ("ChunkFrameID", parser.get_integer_value),
                                  ("ChunkExposureTime", parser.get_float_value)]:
                    try:
                        chunks[name] = get(buf, name)
                    except Exception:  # noqa: BLE001 - a disabled chunk is absent
                        chunks[name] = None
                rec["chunks"] = chunks
            c, mx = centroid(buf.get_data(), w, h, bpp)
            rec.update({"centroid": c, "max": mx})
        out["buffers"].append(rec)
        stream.push_buffer(buf)
    cam.stop_acquisition()
    n_missing = stream.get_info_uint64_by_name("n_missing_packets")
    n_resent = stream.get_info_uint64_by_name("n_resent_packets")
    out["n_missing_packets"] = n_missing
    out["n_resent_packets"] = n_resent
    print(json.dumps(out))


if __name__ == "__main__":
    main()
