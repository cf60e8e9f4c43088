#!/usr/bin/env python3
"""Convert the Yale Bright Star Catalogue, 5th revised edition (ADC/CDS V/50, file
`catalog`, 197-byte fixed-width records) into the compact CSV hilcam reads.

    python3 scripts/bsc5_csv.py bsc5.dat > scenes/stars/bsc5.csv

Keeps every entry that has a J2000 position and a V magnitude (the 14 non-stellar or
removed entries have neither) and writes `hr,ra_deg,dec_deg,vmag,name` with RA and Dec
(equinox and epoch J2000.0) in decimal degrees. Byte columns from the catalogue's ReadMe.
"""
import sys


def field(rec, a, b):
    """Bytes a..b of the record (1-based, inclusive, as the ReadMe numbers them)."""
    return rec[a - 1:b].strip()


def main(path):
    out = ["# Yale Bright Star Catalogue, 5th rev. ed. (Hoffleit & Warren 1991, ADC/CDS V/50);",
           "# J2000.0 positions, Johnson V. Provenance and conversion: docs/stars.md.",
           "hr,ra_deg,dec_deg,vmag,name"]
    with open(path, encoding="ascii") as f:
        for rec in f:
            rec = rec.rstrip("\n").ljust(197)
            ra_h, vmag = field(rec, 76, 77), field(rec, 103, 107)
            if not ra_h or not vmag:
                continue
            ra = 15.0 * (int(ra_h) + int(field(rec, 78, 79)) / 60.0 + float(field(rec, 80, 83)) / 3600.0)
            dec = int(field(rec, 85, 86)) + int(field(rec, 87, 88)) / 60.0 + int(field(rec, 89, 90)) / 3600.0
            if field(rec, 84, 84) == "-":
                dec = -dec
            name = " ".join(field(rec, 5, 14).split())
            out.append(f"{int(field(rec, 1, 4))},{ra:.5f},{dec:.5f},{float(vmag):.2f},{name}")
    sys.stdout.write("\n".join(out) + "\n")


if __name__ == "__main__":
    main(sys.argv[1])
