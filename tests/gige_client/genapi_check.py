"""The GenICam reference GenApi (PyPI `genicam`) on hilcam's camera.

Usage: genapi_check.py XML_FILE ADDRESS [Feature=value ...]
Loads the XML (the reference parser rejects what the schema and its rules do not allow),
connects its Device port to the camera at ADDRESS over GVCP (READMEM / WRITEMEM with
control privilege), writes the features in order, then prints one JSON object: each
standard feature's interface type and value as the reference implementation reads it.
"""
import json
import socket
import struct
import sys

from genicam import genapi

FEATURES = [
    "DeviceVendorName", "DeviceModelName", "DeviceFirmwareVersion", "DeviceSerialNumber", "DeviceUserID",
    "SensorWidth", "SensorHeight", "WidthMax", "HeightMax", "Width", "Height", "OffsetX", "OffsetY",
    "PixelFormat", "PayloadSize", "AcquisitionMode", "AcquisitionFrameRate", "ExposureMode", "ExposureTime",
    "ExposureAuto", "TriggerMode", "GevSCPD", "GevSCPSPacketSize", "TLParamsLocked", "ChunkModeActive",
    "ChunkSelector", "ChunkEnable",
]


class Gvcp:
    def __init__(self, address):
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.settimeout(2.0)
        self.peer = (address, 3956)
        self.req = 0

    def cmd(self, code, payload):
        self.req = self.req % 0xFFFF + 1
        self.sock.sendto(struct.pack(">BBHHH", 0x42, 1, code, len(payload), self.req) + payload, self.peer)
        while True:
            data = self.sock.recv(2048)
            status, answer, length, ack = struct.unpack(">HHHH", data[:8])
            if ack == self.req and answer != 0x0089:  # skip PENDING_ACK
                return status, data[8:8 + length]

    def read(self, address, length):
        out = b""
        while len(out) < length:
            n = min(512, length - len(out))
            aligned = (n + 3) & ~3
            status, data = self.cmd(0x0084, struct.pack(">IHH", address + len(out), 0, aligned))
            if status:
                raise IOError("READMEM %#x status %#x" % (address, status))
            out += data[4:4 + n]
        return out

    def write(self, address, data):
        status, _ = self.cmd(0x0086, struct.pack(">I", address) + data)
        if status:
            raise IOError("WRITEMEM %#x status %#x" % (address, status))


class Port(genapi.AbstractPort):
    def __init__(self, gvcp):
        super().__init__()
        self.gvcp = gvcp

    def is_open(self):
        return True

    def read(self, address, length):
        return self.gvcp.read(address, length)

    def write(self, address, value):
        self.gvcp.write(address, bytes(value))

    def get_access_mode(self):
        return genapi.EAccessMode.RW


def main():
    xml_file, address = sys.argv[1], sys.argv[2]
    nm = genapi.NodeMap()
    nm.load_xml_from_file(xml_file)
    gvcp = Gvcp(address)
    gvcp.write(0x0A00, struct.pack(">I", 2))  # CCP: control privilege
    port = Port(gvcp)
    nm.connect(port, "Device")
    for kv in sys.argv[3:]:
        name, value = kv.split("=", 1)
        node = nm.get_node(name)
        if isinstance(node, genapi.IEnumeration):
            node.from_string(value)
        elif isinstance(node, genapi.IString):
            node.value = value
        elif isinstance(node, genapi.IFloat):
            node.value = float(value)
        else:
            node.value = int(value)
    out = {}
    for f in FEATURES:
        node = nm.get_node(f)
        kind = type(node).__name__
        try:
            value = node.to_string() if isinstance(node, genapi.IEnumeration) else node.value
        except Exception as e:  # noqa: BLE001 - reported, the test decides
            value = "error: %s" % e
        entry = {"type": kind, "value": value}
        if isinstance(node, genapi.IInteger):
            entry["max"] = node.max
        out[f] = entry
    gvcp.write(0x0A00, struct.pack(">I", 0))
    print(json.dumps(out))


if __name__ == "__main__":
    main()
