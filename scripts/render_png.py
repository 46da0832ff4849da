"""Renders a citygen GLB to a PNG without a browser: flat-shaded triangles, z-buffer, numpy only.

python scripts/render_png.py IN.glb OUT.png bird
python scripts/render_png.py IN.glb OUT.png street [DX DY [FX FY]]   (eye 1.7 m above the ground at the model centre
    (the middle of its bounding box)
    + (DX, DY) metres east/north, looking along (FX, FY))
python scripts/render_png.py IN.glb OUT.png at X Y FX FY   (eye 1.7 m above the ground at (X, Y) of the file's
    local frame, metres east/north, looking along (FX, FY)); numpy is in the validators' venv:
    $CITYGEN_VALIDATE_HOME/venv/bin/python (default ~/.cache/citygen-validate).
The ground is the file's `terrain` node (a run with --dem) when it has one, drawn as a mesh, the
eye 1.7 m above the terrain under it; otherwise a flat plane at z = 0.
For where headless Chromium (scripts/screenshot) is missing. Like a glTF viewer, it culls the
back faces of single-sided materials, blends BLEND materials over the opaque scene (back to
front) and encodes the linear colours to sRGB. With ZFIGHT=1 in the environment it emulates a 24-bit depth buffer (near plane 0.1 m,
depth jittered by half a step per triangle and pixel), so coincident faces show the speckled
seams a GPU draws. A material with a baseColorTexture (citygen --textures) is drawn with it:
TEXCOORD_0 interpolated perspective-correct, the PNG sampled nearest with REPEAT wrap and
multiplied by baseColorFactor (the PNG decoded here, 8-bit grey/RGB/RGBA, numpy only)."""
import os
import json, struct, sys, zlib, numpy as np
glb, out, mode = sys.argv[1], sys.argv[2], sys.argv[3]
d = open(glb, 'rb').read()
n = struct.unpack('<I', d[12:16])[0]
j = json.loads(d[20:20+n]); bin_ = d[20+n+8:]
def acc(i):
    a = j['accessors'][i]; v = j['bufferViews'][a['bufferView']]
    off = v.get('byteOffset', 0) + a.get('byteOffset', 0)
    comp = {5126: np.float32, 5125: np.uint32, 5123: np.uint16}[a['componentType']]
    k = {'SCALAR': 1, 'VEC2': 2, 'VEC3': 3}[a['type']]
    stride = v.get('byteStride')
    if stride and k > 1 and stride != 4 * k:
        raw = np.frombuffer(bin_, np.uint8, a['count'] * stride, off).reshape(-1, stride)
        return raw[:, :4 * k].copy().view(np.float32).reshape(-1, k)
    return np.frombuffer(bin_, comp, a['count'] * k, off).reshape(-1, k) if k > 1 else np.frombuffer(bin_, comp, a['count'], off)
def png_decode(b):
    """An 8-bit, non-interlaced PNG (grey, RGB or RGBA) as an (h, w, 3) float array in 0..1 (sRGB)."""
    i, idat = 8, b''
    while i < len(b):
        ln = struct.unpack('>I', b[i:i+4])[0]; t = b[i+4:i+8]; c = b[i+8:i+8+ln]; i += 12 + ln
        if t == b'IHDR': w, h, depth, ctype = struct.unpack('>IIBB', c[:10])
        elif t == b'IDAT': idat += c
    ch = {0: 1, 2: 3, 6: 4}[ctype]; raw = zlib.decompress(idat); row = w * ch
    out = np.zeros((h, row), np.int32); prev = np.zeros(row, np.int32)
    for y in range(h):
        f = raw[y * (row + 1)]; cur = np.frombuffer(raw, np.uint8, row, y * (row + 1) + 1).astype(np.int32)
        if f == 0: r = cur
        elif f == 2: r = (cur + prev) & 255
        else:
            r = np.zeros(row, np.int32)
            for x in range(row):
                a = r[x - ch] if x >= ch else 0; up = prev[x]; c2 = prev[x - ch] if x >= ch else 0
                if f == 1: pr = a
                elif f == 3: pr = (a + up) // 2
                else:
                    p0 = a + up - c2; pa, pb, pc = abs(p0 - a), abs(p0 - up), abs(p0 - c2)
                    pr = a if pa <= pb and pa <= pc else (up if pb <= pc else c2)
                r[x] = (cur[x] + pr) & 255
        out[y] = r; prev = r
    px = out.reshape(h, w, ch)[..., :3] if ch >= 3 else np.repeat(out.reshape(h, w, 1), 3, 2)
    return px / 255.0
images = []
for im in j.get('images', []):
    v = j['bufferViews'][im['bufferView']]; o = v.get('byteOffset', 0)
    srgb = png_decode(bin_[o:o + v['byteLength']])
    images.append(np.where(srgb <= 0.04045, srgb / 12.92, ((srgb + 0.055) / 1.055) ** 2.4))  # to linear
tris = []; cols = []; alphas = []; twosided = []; ground = []; uvs = []; texs = []
def walk(i, t):
    nd = j['nodes'][i]; t = t + np.array(nd.get('translation', [0, 0, 0]))
    if 'mesh' in nd:
        for p in j['meshes'][nd['mesh']]['primitives']:
            pos = acc(p['attributes']['POSITION']) + t; idx = acc(p['indices']).reshape(-1, 3)
            mat = j['materials'][p['material']]; m = mat['pbrMetallicRoughness'].get('baseColorFactor', [1, 1, 1, 1])
            blend = mat.get('alphaMode') == 'BLEND'
            tris.append(pos[idx]); cols.append(np.tile(m[:3], (len(idx), 1)))
            alphas.append(np.full(len(idx), m[3] if blend else 1.0)); twosided.append(np.full(len(idx), bool(mat.get('doubleSided'))))
            ground.append(np.full(len(idx), nd.get('name') == 'terrain'))
            tref = mat['pbrMetallicRoughness'].get('baseColorTexture')
            if tref is not None and 'TEXCOORD_0' in p['attributes']:
                uvs.append(acc(p['attributes']['TEXCOORD_0'])[idx]); texs.append(np.full(len(idx), j['textures'][tref['index']]['source']))
            else:
                uvs.append(np.zeros((len(idx), 3, 2))); texs.append(np.full(len(idx), -1))
    for c in nd.get('children', []): walk(c, t)
for r in j['scenes'][0]['nodes']: walk(r, np.zeros(3))
T = np.concatenate(tris).astype(np.float64); C = np.concatenate(cols); A = np.concatenate(alphas); D = np.concatenate(twosided)
UV = np.concatenate(uvs); TX = np.concatenate(texs)
G = np.concatenate(ground)  # the triangles of the glTF `terrain` node (a run with --dem)
# glTF y up, z south: world x east, y north, z up
W = np.stack([T[..., 0], -T[..., 2], T[..., 1]], -1)
P = W.reshape(-1, 3); c = (P.min(0) + P.max(0)) / 2; ext = np.ptp(W.reshape(-1, 3)[:, :2], 0).max()
def terrain_z(px, py):
    """The height of the terrain mesh under (px, py): the highest terrain triangle containing the
    point in plan, 0 without a terrain node (the flat ground of a run without --dem); the nearest
    terrain vertex's height when the point is outside every triangle."""
    if not G.any(): return 0.0
    t = W[G]; (ax, ay, az), (bx, by, bz), (cx, cy, cz) = t[:, 0].T, t[:, 1].T, t[:, 2].T
    den = (by - cy) * (ax - cx) + (cx - bx) * (ay - cy); ok = np.abs(den) > 1e-12; den = np.where(ok, den, 1.0)
    l1 = ((by - cy) * (px - cx) + (cx - bx) * (py - cy)) / den; l2 = ((cy - ay) * (px - cx) + (ax - cx) * (py - cy)) / den
    l3 = 1 - l1 - l2; e = -1e-9; hit = ok & (l1 >= e) & (l2 >= e) & (l3 >= e)
    if hit.any(): return float((l1 * az + l2 * bz + l3 * cz)[hit].max())
    v = t.reshape(-1, 3); return float(v[np.argmin((v[:, 0] - px) ** 2 + (v[:, 1] - py) ** 2), 2])
Wd, H = 1400, 900
if mode == 'bird':
    eye = c + np.array([-0.5, -0.9, 0.8]) * ext * 0.9; f = 1.6
else:  # street / at: 1.7 m above the ground
    at = np.zeros(2) if mode == 'at' else c[:2]
    # DX DY (X Y for `at`) FX FY are optional: 0 0 0 1 (at the centre, looking north) where left out.
    dx, dy, fx, fy = [float(a) for a in sys.argv[4:8]] + [0.0, 0.0, 0.0, 1.0][len(sys.argv[4:8]):]
    ex, ey = at[0] + dx, at[1] + dy
    eye = np.array([ex, ey, terrain_z(ex, ey) + 1.7]); f = 1.0
    tgt = eye + np.array([fx, fy, 0.15])
fwd = (c - eye) if mode == 'bird' else (tgt - eye); fwd /= np.linalg.norm(fwd)
right = np.cross(fwd, [0, 0, 1]); right /= np.linalg.norm(right); up = np.cross(right, fwd)
V = W - eye; x = V @ right; y = V @ up; z = V @ fwd
nrm = np.cross(W[:, 1] - W[:, 0], W[:, 2] - W[:, 0]); nl = np.linalg.norm(nrm, axis=1) + 1e-12; nrm /= nl[:, None]
light = np.array([0.4, -0.5, 0.75]); light /= np.linalg.norm(light)
shade = 0.35 + 0.65 * np.abs(nrm @ light)
img = np.full((H, Wd, 3), [0.57, 0.71, 0.89]); zb = np.full((H, Wd), np.inf)
s = f * Wd / 2
if mode != 'bird' and not G.any():  # a flat ground at z = 0 (no terrain mesh): pixels whose ray points down
    gx, gy = np.meshgrid((np.arange(Wd) + 0.5 - Wd / 2) / s, (H / 2 - np.arange(H) - 0.5) / s)
    dz = fwd[2] + gx * right[2] + gy * up[2]
    img[dz < 0] = [0.55, 0.55, 0.53]
facing = (nrm * (eye - W[:, 0])).sum(1) > 0  # front side towards the eye
zfight = os.environ.get('ZFIGHT') == '1'
NEAR = 0.5
def clip_near(k):
    """Triangle k in camera space cut to z >= NEAR (Sutherland-Hodgman against one plane), as a
    fan of triangles: a terrain triangle under the eye reaches behind it and is drawn in part."""
    v = np.concatenate([np.stack([x[k], y[k], z[k]], 1), UV[k]], 1); inside = v[:, 2] >= NEAR  # uv clipped along
    if inside.all(): return [v]
    if not inside.any(): return []
    poly = []
    for i in range(3):
        p, q = v[i], v[(i + 1) % 3]
        if p[2] >= NEAR: poly.append(p)
        if (p[2] >= NEAR) != (q[2] >= NEAR): poly.append(p + (q - p) * (NEAR - p[2]) / (q[2] - p[2]))
    return [np.array([poly[0], poly[i], poly[i + 1]]) for i in range(1, len(poly) - 1)]
def raster(v, k):
    px = Wd / 2 + s * v[:, 0] / v[:, 2]; py = H / 2 - s * v[:, 1] / v[:, 2]
    x0, x1 = max(int(px.min()), 0), min(int(px.max()) + 1, Wd); y0, y1 = max(int(py.min()), 0), min(int(py.max()) + 1, H)
    if x0 >= x1 or y0 >= y1: return
    gx, gy = np.meshgrid(np.arange(x0, x1) + 0.5, np.arange(y0, y1) + 0.5)
    (ax, bx, cx), (ay, by, cy) = px, py
    den = (by - cy) * (ax - cx) + (cx - bx) * (ay - cy)
    if abs(den) < 1e-9: return
    l1 = ((by - cy) * (gx - cx) + (cx - bx) * (gy - cy)) / den; l2 = ((cy - ay) * (gx - cx) + (ax - cx) * (gy - cy)) / den; l3 = 1 - l1 - l2
    inside = (l1 >= 0) & (l2 >= 0) & (l3 >= 0)
    zz = 1 / (l1 / v[0, 2] + l2 / v[1, 2] + l3 / v[2, 2])  # perspective-correct: 1/z is linear on the screen
    sub = zb[y0:y1, x0:x1]
    if zfight:  # 24-bit depth of a 0.1 m near plane: one step is z^2 / (0.1 * 2^24)
        q = zz * zz / (0.1 * 2 ** 24); jit = np.random.default_rng(k).random(zz.shape) - 0.5
        m = inside & (np.floor(zz / q + jit) < np.floor(sub / q + 0.0))
    else:
        m = inside & (zz < sub)
    col = C[k] * shade[k]
    if TX[k] >= 0:  # textured: perspective-correct uv, nearest texel, REPEAT
        t = v[:, 3:5]; tex = images[TX[k]]; th, tw = tex.shape[:2]
        uu = (l1 * t[0, 0] / v[0, 2] + l2 * t[1, 0] / v[1, 2] + l3 * t[2, 0] / v[2, 2]) * zz
        vv = (l1 * t[0, 1] / v[0, 2] + l2 * t[1, 1] / v[1, 2] + l3 * t[2, 1] / v[2, 2]) * zz
        ti = (np.floor(np.mod(vv, 1.0) * th).astype(int)) % th; tj = (np.floor(np.mod(uu, 1.0) * tw).astype(int)) % tw
        col = tex[ti, tj] * (C[k] * shade[k])
        col = col[m]
    if A[k] >= 1.0:
        sub[m] = zz[m]; img[y0:y1, x0:x1][m] = col
    else:
        img[y0:y1, x0:x1][m] = A[k] * col + (1 - A[k]) * img[y0:y1, x0:x1][m]
order = np.argsort(-z.min(1)); opaque = A >= 1.0
for k in np.concatenate([order[opaque[order]], order[~opaque[order]]]):
    if z[k].max() < NEAR: continue
    if not (facing[k] or D[k]): continue
    for v in clip_near(k): raster(v, k)
img = np.clip(img, 0, 1); img = np.where(img <= 0.0031308, img * 12.92, 1.055 * img ** (1 / 2.4) - 0.055)  # linear to sRGB, as viewers show it
px8 = (np.clip(img, 0, 1) * 255).astype(np.uint8)
raw = b''.join(b'\x00' + px8[r].tobytes() for r in range(H))
chunk = lambda t, b: struct.pack('>I', len(b)) + t + b + struct.pack('>I', zlib.crc32(t + b) & 0xffffffff)
open(out, 'wb').write(b'\x89PNG\r\n\x1a\n' + chunk(b'IHDR', struct.pack('>IIBBBBB', Wd, H, 8, 2, 0, 0, 0)) + chunk(b'IDAT', zlib.compress(raw, 6)) + chunk(b'IEND', b''))
print(len(T), 'triangles')
