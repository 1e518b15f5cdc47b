#!/usr/bin/env python3
"""Writes the glTF seed corpus (fuzz/corpus/fuzz_gltf) from scenes `probekit scene` generates.

Each seed is one self-contained file (buffers and images as data: URIs, or a GLB), because the
fuzz target loads from memory and its folder holds no other files:
  python3 fuzz/seeds/make_gltf_seeds.py build/tools/probekit fuzz/corpus/fuzz_gltf
"""
import base64
import json
import os
import struct
import subprocess
import sys
import tempfile


def embed(gltf_path):
    """The scene with every external buffer and image inlined as a data: URI."""
    folder = os.path.dirname(gltf_path)
    with open(gltf_path) as f:
        doc = json.load(f)
    for key, mime in (("buffers", "application/octet-stream"), ("images", "image/png")):
        for item in doc.get(key, []):
            uri = item.get("uri")
            if uri and not uri.startswith("data:"):
                with open(os.path.join(folder, uri), "rb") as f:
                    item["uri"] = "data:%s;base64,%s" % (mime, base64.b64encode(f.read()).decode())
    return doc


def glb(doc):
    """The scene as GLB: the first buffer becomes the BIN chunk, images become buffer views."""
    doc = json.loads(json.dumps(doc))
    binary = bytearray()
    buffers = doc.get("buffers", [])
    if buffers:
        binary += base64.b64decode(buffers[0]["uri"].split(",", 1)[1])
        del buffers[0]["uri"]
    for image in doc.get("images", []):
        data = base64.b64decode(image.pop("uri").split(",", 1)[1])
        while len(binary) % 4:
            binary.append(0)
        doc.setdefault("bufferViews", []).append(
            {"buffer": 0, "byteOffset": len(binary), "byteLength": len(data)})
        image["bufferView"] = len(doc["bufferViews"]) - 1
        image["mimeType"] = "image/png"
        binary += data
    if buffers:
        buffers[0]["byteLength"] = len(binary)
    text = json.dumps(doc, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    binary += b"\0" * (-len(binary) % 4)
    chunks = struct.pack("<I4s", len(text), b"JSON") + text
    if binary:
        chunks += struct.pack("<I4s", len(binary), b"BIN\0") + bytes(binary)
    return struct.pack("<4sII", b"glTF", 2, 12 + len(chunks)) + chunks


def features():
    """A small hand-made file with what the generated scenes lack: every light type, a node
    hierarchy with matrix and TRS, a triangle strip and fan, a sparse accessor, unsigned byte and
    short indices, normalized texture coordinates, an emissive strength."""
    positions = struct.pack("<12f", 0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0)
    indices_u8 = struct.pack("<6B", 0, 1, 2, 2, 1, 3) + b"\0\0"
    indices_u16 = struct.pack("<4H", 0, 1, 2, 3)
    uvs = struct.pack("<8B", 0, 0, 255, 0, 0, 255, 255, 255)
    sparse_idx = struct.pack("<H", 3) + b"\0\0"
    sparse_val = struct.pack("<3f", 2, 2, 0)
    data = positions + indices_u8 + indices_u16 + uvs + sparse_idx + sparse_val
    views = [(0, 48), (48, 8), (56, 8), (64, 8), (72, 4), (76, 12)]
    doc = {
        "asset": {"version": "2.0", "generator": "probekit fuzz seed"},
        "extensionsUsed": ["KHR_lights_punctual", "KHR_materials_emissive_strength"],
        "buffers": [{"byteLength": len(data), "uri": "data:application/octet-stream;base64," +
                     base64.b64encode(data).decode()}],
        "bufferViews": [{"buffer": 0, "byteOffset": o, "byteLength": n} for o, n in views],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
             "min": [0, 0, 0], "max": [1, 1, 0]},
            {"bufferView": 1, "componentType": 5121, "count": 6, "type": "SCALAR"},
            {"bufferView": 2, "componentType": 5123, "count": 4, "type": "SCALAR"},
            {"bufferView": 3, "componentType": 5121, "normalized": True, "count": 4,
             "type": "VEC2"},
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
             "sparse": {"count": 1, "indices": {"bufferView": 4, "componentType": 5123},
                        "values": {"bufferView": 5}}},
        ],
        "materials": [
            {"pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.5, 0.2, 1]}},
            {"emissiveFactor": [1, 0.9, 0.8],
             "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 4}}},
        ],
        "meshes": [
            {"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 3}, "indices": 1,
                             "material": 0}]},
            {"primitives": [{"attributes": {"POSITION": 4}, "indices": 2, "mode": 5,
                             "material": 1},
                            {"attributes": {"POSITION": 0}, "mode": 6}]},
        ],
        "extensions": {"KHR_lights_punctual": {"lights": [
            {"type": "point", "intensity": 10, "color": [1, 0.9, 0.8], "range": 20},
            {"type": "spot", "intensity": 50, "spot": {"innerConeAngle": 0.2,
                                                       "outerConeAngle": 0.6}},
            {"type": "directional", "intensity": 3},
        ]}},
        "nodes": [
            {"children": [1, 2], "translation": [0, 1, 0], "rotation": [0, 0.7071068, 0, 0.7071068],
             "scale": [2, 2, 2]},
            {"mesh": 0},
            {"mesh": 1, "matrix": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 3, 0, 0, 1]},
            {"translation": [0, 3, 0], "extensions": {"KHR_lights_punctual": {"light": 0}}},
            {"translation": [0, 3, 2], "extensions": {"KHR_lights_punctual": {"light": 1}}},
            {"rotation": [-0.5, 0, 0, 0.8660254], "extensions": {"KHR_lights_punctual": {"light": 2}}},
        ],
        "scenes": [{"nodes": [0, 3, 4, 5]}],
        "scene": 0,
    }
    return doc


def main():
    probekit, out = sys.argv[1], sys.argv[2]
    os.makedirs(out, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        for name in ("cornell", "lone-box"):
            path = os.path.join(tmp, name + ".gltf")
            subprocess.run([probekit, "scene", name, "-o", path], check=True,
                           stdout=subprocess.DEVNULL)
            doc = embed(path)
            with open(os.path.join(out, name + ".gltf"), "w") as f:
                json.dump(doc, f, separators=(",", ":"))
            with open(os.path.join(out, name + ".glb"), "wb") as f:
                f.write(glb(doc))
    doc = features()
    with open(os.path.join(out, "features.gltf"), "w") as f:
        json.dump(doc, f, separators=(",", ":"))
    with open(os.path.join(out, "features.glb"), "wb") as f:
        f.write(glb(doc))


if __name__ == "__main__":
    main()
