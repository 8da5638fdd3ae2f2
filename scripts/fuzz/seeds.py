#!/usr/bin/env python3
"""Seed corpora of the fuzz targets, generated from the repository's fixtures and shipped
models (nothing is committed): fuzz/corpus/<target>/seed-*.

    python3 scripts/fuzz/seeds.py
"""
import base64
import gzip
import io
import json
import pathlib
import struct
import tarfile
import zipfile
import zlib

ROOT = pathlib.Path(__file__).resolve().parents[2]
FEATURES = ROOT / "tests/fixtures/features"
CORPUS = ROOT / "fuzz/corpus"


def png_gray(width, height, value):
    raw = b"".join(b"\0" + bytes([value]) * width for _ in range(height))

    def chunk(kind, data):
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(raw))
            + chunk(b"IEND", b""))


def write(target, name, data):
    out = CORPUS / target
    out.mkdir(parents=True, exist_ok=True)
    (out / f"seed-{name}").write_bytes(data)


# A 96 × 72 colour JPEG of a ball (4:2:0, EXIF orientation 6), made with Pillow: for the full
# and the scaled (DCT-domain) JPEG decoders.
BALL_JPEG = (
    "/9j/4AAQSkZJRgABAQAAAQABAAD/4QAiRXhpZgAATU0AKgAAAAgAAQESAAMAAAABAAYAAAAAAAD/2wBDAAgGBgcG"
    "BQgHBwcJCQgKDBQNDAsLDBkSEw8UHRofHh0aHBwgJC4nICIsIxwcKDcpLDAxNDQ0Hyc5PTgyPC4zNDL/2wBDAQkJ"
    "CQwLDBgNDRgyIRwhMjIyMjIyMjIyMjIyMjIyMjIyMjIyMjIyMjIyMjIyMjIyMjIyMjIyMjIyMjIyMjIyMjL/wAAR"
    "CABIAGADASIAAhEBAxEB/8QAHwAAAQUBAQEBAQEAAAAAAAAAAAECAwQFBgcICQoL/8QAtRAAAgEDAwIEAwUFBAQA"
    "AAF9AQIDAAQRBRIhMUEGE1FhByJxFDKBkaEII0KxwRVS0fAkM2JyggkKFhcYGRolJicoKSo0NTY3ODk6Q0RFRkdI"
    "SUpTVFVWV1hZWmNkZWZnaGlqc3R1dnd4eXqDhIWGh4iJipKTlJWWl5iZmqKjpKWmp6ipqrKztLW2t7i5usLDxMXG"
    "x8jJytLT1NXW19jZ2uHi4+Tl5ufo6erx8vP09fb3+Pn6/8QAHwEAAwEBAQEBAQEBAQAAAAAAAAECAwQFBgcICQoL"
    "/8QAtREAAgECBAQDBAcFBAQAAQJ3AAECAxEEBSExBhJBUQdhcRMiMoEIFEKRobHBCSMzUvAVYnLRChYkNOEl8RcY"
    "GRomJygpKjU2Nzg5OkNERUZHSElKU1RVVldYWVpjZGVmZ2hpanN0dXZ3eHl6goOEhYaHiImKkpOUlZaXmJmaoqOk"
    "paanqKmqsrO0tba3uLm6wsPExcbHyMnK0tPU1dbX2Nna4uPk5ebn6Onq8vP09fb3+Pn6/9oADAMBAAIRAxEAPwDl"
    "oqtL0qrFVpelc5sDVWl71Zaq0vehAUZe9VWrq9J8Kz6mFnnJitmGRj7zehHoP8+9dLD4V021hCC1SQ92kG4k/j/S"
    "k5pBytnl61bi613d1olkFwLWEYGBhBxXN3+mLAS0I2+3ampJhy2K0VWV6VUt5FckDhlOCD1FW16UANeqk3erb1Um"
    "70IB0VWl6VViq0vSgAatPw/pK6heGadA0EZ6H+JvTHpWY1dp4fRINPi2jlhuJ9SamTshpanQRxqqgAVHNjFHnDFV"
    "5puKxNCldYwa53UACDWzdTDB5rnr+bg81pEhnJ6m8lrL58Jw6+vQ+x9q1rO5jvLVJ4idjjjIwR6isTV5AVal8KXD"
    "yQXEDHKRsGX2znI+nH6mtWtCL6m89VJu9W3qpN3pIY6KrS9KqxVaXpQANXUaVdAWkQz0UCuXaprO+8h/LJ9xUtXQ"
    "0ztftQx1qtNdcHmsYagCPvVXmvxjrUqI7ly6uuDzXPX91weaLq/GDzXO39+MHmtIxJbKWqXO7IB61d8Ig77s7jgB"
    "Bt7Hrz/n1rnppTK5Y11/hqzFvpvnEESTnccjHA6f1OferloiFua71Um71beqk3eoRY6KrS9KqxVaXpQANVS4TeOG"
    "KkcgjsattVaXvQgMw6q8Ehim+Vx+o9RUcmrgj71S3cMc6FJVDLnNY8ukIXJjlZV/ukZqlYnULnVN2QDmsuWZpWyx"
    "rQXRiSczgeny/wD160LPRraPBlBlbOfm4H5f41V0hWZS0bRzfOJpwRbKfoXPoPb3/wAjtV6VWiqyvSs27lJWGvVS"
    "bvVt6qTd6EMdFVpelFFAA1Vpe9FFCAoy96qtRRVIkFq3F1oooAvRVZXpRRUlDXqpN3oooQH/2Q=="
)


def images():
    seeds = {p.name: p.read_bytes() for p in sorted(FEATURES.glob("*.png"))}
    seeds["tiny.png"] = png_gray(1, 1, 128)
    seeds["flat64.png"] = png_gray(64, 64, 200)
    seeds["tiny.pfm"] = b"Pf\n2 2\n-1\n" + struct.pack("<4f", 0.5, 1.0, 0.0, 2.0)
    seeds["tiny.hdr"] = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 2 +X 2\n" + bytes(
        [128, 128, 128, 129] * 4)
    seeds["tiny.pgm"] = b"P5\n2 2\n255\n\x00\x40\x80\xff"
    seeds["exr-magic"] = bytes([0x76, 0x2F, 0x31, 0x01, 2, 0, 0, 0])
    seeds["ball-rotated.jpg"] = base64.b64decode(BALL_JPEG)
    return seeds


def multipart(fields, boundary=b"B"):
    body = b""
    for name, value, is_file in fields:
        body += b"--" + boundary + b"\r\n"
        disposition = b'Content-Disposition: form-data; name="' + name + b'"'
        if is_file:
            disposition += b'; filename="f"\r\nContent-Type: application/octet-stream'
        body += disposition + b"\r\n\r\n" + value + b"\r\n"
    return body + b"--" + boundary + b"--\r\n"


def main():
    for name, data in images().items():
        write("decode_features", name, data)

    # multipart_router: selector byte (route | content type << 2), then the body.
    gray8 = (FEATURES / "sphere_gray8.png").read_bytes()
    circle = [(b"cx", b"52.35", False), (b"cy", b"48.7", False), (b"r", b"40.3", False)]
    form = multipart([(b"image", gray8, True), (b"white", b"1.0", False)] + circle)
    write("multipart_router", "classify", bytes([0]) + form)
    write("multipart_router", "named", bytes([1]) + form)
    write("multipart_router", "auto", bytes([0]) + multipart([(b"image", gray8, True)]))
    mask = png_gray(106, 99, 255)
    write("multipart_router", "mask", bytes([2]) + multipart(
        [(b"image", gray8, True), (b"mask", mask, True), (b"encoding", b"gamma:2.2", False),
         (b"include", b"features,explain", False)]))
    infer = {"inputs": [
        {"name": "image", "datatype": "BYTES", "shape": [1],
         "data": [base64.b64encode(gray8).decode()]},
        {"name": "white", "datatype": "FP64", "shape": [1], "data": [1.0]},
        {"name": "cx", "datatype": "FP64", "shape": [1], "data": [52.35]},
        {"name": "cy", "datatype": "FP64", "shape": [1], "data": [48.7]},
        {"name": "r", "datatype": "FP64", "shape": [1], "data": [40.3]}]}
    write("multipart_router", "infer", bytes([3 | 3 << 2]) + json.dumps(infer).encode())

    # model_file: the shipped models with their exemplars cut to three (the target
    # recomputes the checksum, so the seeds need not carry a valid one).
    for name in ("ward6", "ward11"):
        model = json.loads((ROOT / "models" / name / "1/model.json").read_text())
        model["exemplars"] = model.get("exemplars", [])[:3]
        write("model_file", name, json.dumps(model).encode())

    # archive_unpack: a dataset archive as tar, tar.gz and zip (a manifest and an image),
    # and the same with a member that leaves the folder and a link.
    for name, data in archives().items():
        write("archive_unpack", name, data)


def tar_of(members, links=()):
    out = io.BytesIO()
    with tarfile.open(fileobj=out, mode="w", format=tarfile.GNU_FORMAT) as tar:
        for name, data in members:
            info = tarfile.TarInfo(name)
            info.size = len(data)
            tar.addfile(info, io.BytesIO(data))
        for name, target in links:
            info = tarfile.TarInfo(name)
            info.type = tarfile.SYMTYPE
            info.linkname = target
            tar.addfile(info)
    return out.getvalue()


def zip_of(members):
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, data in members:
            archive.writestr(name, data)
    return out.getvalue()


def archives():
    image = (FEATURES / "sphere_gray8.png").read_bytes()
    manifest = (b"path,class,illumination,cx,cy,r,white\n"
                b"probe0/a.png,shiny,probe0,52.35,48.7,40.3,1.0\n"
                b"../b.png,shiny,probe1,,,,\n/etc/passwd,shiny,probe2,,,,\n")
    members = [("manifest.csv", manifest), ("probe0/a.png", image)]
    hostile = members + [("../b.png", b"x"), ("./probe0/../c.png", b"y")]
    return {
        "dataset.tar": tar_of(members),
        "dataset.tar.gz": gzip.compress(tar_of(members), mtime=0),
        "dataset.zip": zip_of(members),
        "hostile.tar": tar_of(hostile, links=[("link", "/etc")]),
        "hostile.zip": zip_of(hostile),
    }


if __name__ == "__main__":
    main()
