#!/usr/bin/env python3
"""rtsl's global illumination (virtual point lights) against Mitsuba 3's path tracer on the Cornell
box of ../shared/scenes, the same scene on both: every surface diffuse grey 0.7 (rtsl: `gimatte`,
Mitsuba: `diffuse`), the point light of examples/scenes/cornell_box.rib casting shadows (rtsl's lights
cast none without `Attribute "light" "shadows" "on"`, as in RenderMan), the same view, 640x480,
direct light and one bounce of indirect light (rtsl `Option "gi" "bounces" [1]`, Mitsuba
`max_depth` 3).

    pip install mitsuba numpy
    cargo build --release
    python3 benches/gi_against_mitsuba.py --reference-spp 1024 --frames 1,10,100 --threads 2

It renders Mitsuba's converged reference, then rtsl's frames with fresh virtual lights each
(`Option "gi" "seed"`), averaged as a still viewer accumulates them, and Mitsuba at the time rtsl
took for each count; it prints each image's mean relative error against the reference (per pixel
and channel |a - r| / (r + 0.01), averaged; and the same over 16x16-pixel blocks' means, which
average away most of the reference's own noise and leave the bias), and the times.
"""
import argparse, os, subprocess, sys, tempfile, time

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), '..')
SHARED = os.path.join(ROOT, '..', 'shared')
ORIGIN, TARGET, FOV = [278, 273, -800], [278, 273, 0], 39.3
LIGHT, INTENSITY = [278, 540, 279.5], 90000.0


def grey_obj(src):
    """The box without its materials, and with absolute indices (Mitsuba refuses relative ones)."""
    vs, fs = [], []
    for line in open(src):
        p = line.split()
        if not p:
            continue
        if p[0] == 'v':
            vs.append(p[1:4])
        elif p[0] == 'f':
            idx = [int(t.split('/')[0]) for t in p[1:]]
            idx = [i if i > 0 else len(vs) + 1 + i for i in idx]
            fs += [(idx[0], idx[k], idx[k + 1]) for k in range(1, len(idx) - 1)]
    out = tempfile.NamedTemporaryFile('w', suffix='.obj', delete=False)
    out.writelines('v %s %s %s\n' % tuple(v) for v in vs)
    out.writelines('f %d %d %d\n' % f for f in fs)
    out.close()
    return out.name


def mitsuba(mesh, spp, threads, seed=0):
    import mitsuba as mi
    import drjit as dr
    mi.set_variant('scalar_rgb')
    dr.set_thread_count(threads)
    T = mi.ScalarTransform4f
    scene = mi.load_dict({
        'type': 'scene', 'integrator': {'type': 'path', 'max_depth': 3},
        'sensor': {'type': 'perspective', 'fov': FOV, 'fov_axis': 'smaller',
                   'to_world': T().look_at(origin=ORIGIN, target=TARGET, up=[0, 1, 0]),
                   'sampler': {'type': 'independent', 'sample_count': spp},
                   'film': {'type': 'hdrfilm', 'width': 640, 'height': 480, 'rfilter': {'type': 'box'},
                            'pixel_format': 'rgb'}},
        'shape': {'type': 'obj', 'filename': mesh, 'face_normals': True,
                  'bsdf': {'type': 'diffuse', 'reflectance': {'type': 'rgb', 'value': [0.7, 0.7, 0.7]}}},
        # Mitsuba's point light gives radiant intensity; rtsl's gimatte divides diffuse() by pi.
        'light': {'type': 'point', 'position': LIGHT, 'intensity': {'type': 'rgb', 'value': INTENSITY * 3.14159265}},
    })
    t0 = time.perf_counter()
    img = mi.render(scene, spp=spp, seed=seed)
    dr.eval(img)
    dr.sync_thread()
    import numpy as np
    return np.array(img)[:, :, :3], time.perf_counter() - t0


def rtsl_frames(rtsl, mesh, frames, paths, threads, workdir):
    """The mean of `frames` rtsl frames, each with virtual lights of its own, and their time."""
    import numpy as np
    total, elapsed = None, 0.0
    for seed in range(frames):
        rib = os.path.join(workdir, 'gi.rib')
        with open(rib, 'w') as f:
            f.write(f'''Format 640 480 1
Projection "perspective" "fov" [{FOV}]
Option "gi" "integer virtuallights" [{paths}] "integer bounces" [1] "integer interleave" [3] "integer seed" [{seed}]
Imager "interleavefilter"
Scale -1 1 1
Translate -278 -273 800
WorldBegin
  Attribute "light" "shadows" "on"
  LightSource "pointlight" 1 "intensity" [{INTENSITY * 3.14159265}] "from" [{LIGHT[0]} {LIGHT[1]} {LIGHT[2]}]
  Color [0.7 0.7 0.7]
  Surface "gimatte"
  ReadArchive "{mesh}"
WorldEnd
''')
        out = os.path.join(workdir, 'frame.exr')
        t0 = time.perf_counter()
        subprocess.run([rtsl, 'render', rib, '-o', out, '-q', '--threads', str(threads)], check=True)
        elapsed += time.perf_counter() - t0
        import mitsuba as mi
        img = np.array(mi.Bitmap(out))[:, :, :3]
        total = img if total is None else total + img
    return total / frames, elapsed


def mre(a, ref, block=1):
    """Mean relative error per pixel and channel, or per `block x block` block's mean (which
    averages away most of the reference's own noise, leaving bias)."""
    import numpy as np
    if block > 1:
        h, w = ref.shape[0] // block * block, ref.shape[1] // block * block
        shrink = lambda x: x[:h, :w].reshape(h // block, block, w // block, block, 3).mean(axis=(1, 3))
        a, ref = shrink(a), shrink(ref)
    return float(np.mean(np.abs(a - ref) / (ref + 0.01)))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('--rtsl', default=os.path.join(ROOT, 'target', 'release', 'rtsl'))
    ap.add_argument('--reference-spp', type=int, default=1024)
    ap.add_argument('--frames', default='1,10,100')
    ap.add_argument('--paths', type=int, default=256, help="rtsl's light paths per frame")
    ap.add_argument('--threads', type=int, default=2)
    ap.add_argument('--save', help='write the images as PREFIX_rtsl_N.png, PREFIX_mitsuba_N.png, PREFIX_reference.png')
    a = ap.parse_args()
    mesh = grey_obj(os.path.join(SHARED, 'scenes', 'cornell_box', 'cornell_box.obj'))
    workdir = tempfile.mkdtemp()
    ref, t = mitsuba(mesh, a.reference_spp, a.threads, seed=12345)
    print(f'reference: Mitsuba path tracer, {a.reference_spp} spp, {t:.1f} s', flush=True)
    if a.save:
        import mitsuba as mi
        mi.util.write_bitmap(f'{a.save}_reference.png', ref)
    for frames in [int(f) for f in a.frames.split(',')]:
        img, t = rtsl_frames(a.rtsl, mesh, frames, a.paths, a.threads, workdir)
        # Mitsuba given the same time: spp from its rate at 16 spp (at least 1).
        _, t16 = mitsuba(mesh, 16, a.threads, seed=1)
        spp = max(1, int(16 * t / t16))
        peer, tp = mitsuba(mesh, spp, a.threads, seed=frames)
        print(f'rtsl {frames} frame(s) of {a.paths} paths: {t:.2f} s, mean relative error {mre(img, ref):.4f} '
              f'(16x16 blocks {mre(img, ref, 16):.4f}); Mitsuba {spp} spp in {tp:.2f} s: {mre(peer, ref):.4f} '
              f'(16x16 blocks {mre(peer, ref, 16):.4f})', flush=True)
        if a.save:
            import mitsuba as mi
            mi.util.write_bitmap(f'{a.save}_rtsl_{frames}.png', img)
            mi.util.write_bitmap(f'{a.save}_mitsuba_{frames}.png', peer)


if __name__ == '__main__':
    sys.exit(main())
