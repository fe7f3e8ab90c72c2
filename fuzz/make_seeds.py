#!/usr/bin/env python3
"""Writes the seed corpus (fuzz/corpus/<target>/) from the repository's assets/ and a few
hand-made inputs that aim at the sandbox's traps. Run from the repository root; the output is
checked in, so this only needs running when the seeds change.

An input is the scene file, then optionally `\\n%%file NAME\\n` and a file that sits beside it
(see `split_files` in crates/scene/src/fuzzing.rs)."""
import json, os

A = "assets"
SEP = b"\n%%file "


def read(name):
    with open(os.path.join(A, name), "rb") as f:
        return f.read()


def framed(main, *files):
    out = main
    for name, body in files:
        out += SEP + name.encode() + b"\n" + body
    return out


def minified(name):
    return json.dumps(json.loads(read(name)), separators=(",", ":")).encode()


def write(target, name, data):
    d = os.path.join("fuzz", "corpus", target)
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, name), "wb") as f:
        f.write(data)


TRI = b"v 0 0 0\nv 1 0 0\nv 0 1 0\n"
cube, mtl, png = read("cube.obj"), read("cube.mtl"), read("checker.png")
write("obj", "cube_alone", cube)
write("obj", "cube_with_mtl", framed(cube, ("cube.mtl", mtl)))
write("obj", "cube_textured", framed(cube, ("cube.mtl", mtl + b"map_Kd checker.png\n"), ("checker.png", png)))
write("obj", "groups_and_materials", framed(
    b"mtllib m.mtl\n" + TRI + b"vt 0 0\nvt 1 0\nvt 0 1\nvn 0 0 1\n"
    b"o a\nusemtl red\nf 1/1/1 2/2/1 3/3/1\ng b\nusemtl tex\nf -3 -2 -1\nf 1 2 3 1\nl 1 2\np 3\n",
    ("m.mtl", b"newmtl red\nKd 1 0 0\nd 0.5\nnewmtl tex\nTr 0.25\nmap_Kd -s 1 1 1 t.png\n"),
    ("t.png", png)))
for i, ref in enumerate([b"link.mtl", b"../outside.mtl", b"zero", b"fifo", b"sub", b"/dev/zero"]):
    write("obj", f"trap_mtllib_{i}", b"mtllib " + ref + b"\n" + TRI + b"f 1 2 3\n")
for i, ref in enumerate([b"link.png", b"../outside.png", b"zero", b"fifo"]):
    write("obj", f"trap_map_kd_{i}", framed(b"mtllib m.mtl\n" + TRI + b"usemtl a\nf 1 2 3\n",
                                           ("m.mtl", b"newmtl a\nmap_Kd " + ref + b"\n")))

gltf = minified("nested.gltf")
write("gltf", "nested_external", framed(gltf, ("nested.bin", read("nested.bin")), ("checker.png", png)))
write("gltf", "nested_embedded", minified("nested_embedded.gltf"))
write("gltf", "nested_glb", read("nested.glb"))
for i, ref in enumerate(["link.bin", "../outside.bin", "zero", "fifo", "sub", "/dev/zero"]):
    write("gltf", f"trap_buffer_{i}", gltf.replace(b'"nested.bin"', json.dumps(ref).encode()))
for i, ref in enumerate(["link.png", "../outside.png", "fifo"]):
    write("gltf", f"trap_image_{i}", framed(gltf.replace(b'"checker.png"', json.dumps(ref).encode()),
                                           ("nested.bin", read("nested.bin"))))
# A buffer that fits the outside file exactly, read as float positions: were the link
# followed, the harness would see the outside floats.
leak = {
    "asset": {"version": "2.0"},
    "buffers": [{"uri": "link.bin", "byteLength": 36}],
    "bufferViews": [{"buffer": 0, "byteLength": 36}],
    "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"}],
    "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
    "nodes": [{"mesh": 0}],
}
write("gltf", "trap_leak_floats", json.dumps(leak, separators=(",", ":")).encode())

key = {"eye": [0, 1.7, 0], "target": [0, 1.7, 10], "up": [0, 1, 0], "fovy_deg": 60, "near": 0.1, "far": 1000}
write("camera_path", "two_keys", json.dumps([key, dict(key, eye=[1, 1.7, 0])]).encode())
write("camera_path", "awkward_keys", json.dumps([
    dict(key, up=[0, 0, 1], target=[0, 1.7, 0]),
    dict(key, near=0, far=-1, fovy_deg=180),
    dict(key, eye=[1e38, -1e38, 3.4e38], near=1e-7),
]).encode())
write("camera_path", "empty", b"[]")
write("camera_path", "not_a_path", b'{"eye": [1, 2]}')
