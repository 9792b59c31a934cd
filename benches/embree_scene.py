#!/usr/bin/env python3
"""Writes an OBJ mesh with a camera and a point light as the scene file of Embree's side of
../shared/bench/embree (`RTSC`: vertex and triangle counts, 16 camera floats, vertices, triangles),
so that a whole frame's own rays can be traced by Embree and by `rtsl bench trace` alike.

    python3 benches/embree_scene.py ../shared/scenes/cornell_box/cornell_box.obj /tmp/cornell.bin \
        --eye 278,273,-800 --look 278,273,0 --fov 39.3 --light 278,540,279.5 --scale 800
    /tmp/embree_bench /tmp/cornell.bin 5 640 480          # built by side-by-side.sh (NO_DYNAMIC=1, THREADS=2)
    rtsl bench trace --mesh ../shared/scenes/cornell_box/cornell_box.obj --eye 278,273,-800 \
        --look 278,273,0 --up 0,1,0 --fov 39.3 --light 278,540,279.5 --scene-scale 800 --size 640x480 --threads 2

Polygons are fanned into triangles as rtsl's OBJ reader fans them; negative indices count back.
"""
import argparse, struct


def triple(text):
    values = [float(v) for v in text.split(',')]
    if len(values) != 3:
        raise argparse.ArgumentTypeError(f'{text}: three numbers, X,Y,Z')
    return values


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('obj')
    ap.add_argument('out')
    ap.add_argument('--eye', type=triple, required=True)
    ap.add_argument('--look', type=triple, required=True)
    ap.add_argument('--up', type=triple, default=[0.0, 1.0, 0.0])
    ap.add_argument('--fov', type=float, required=True, help='vertical field of view, degrees')
    ap.add_argument('--light', type=triple, required=True)
    ap.add_argument('--scale', type=float, required=True, help='scene size (the shadow rays\' offset is 1e-5 of it)')
    a = ap.parse_args()
    vertices, triangles = [], []
    for line in open(a.obj):
        fields = line.split()
        if not fields:
            continue
        if fields[0] == 'v':
            vertices.append([float(v) for v in fields[1:4]])
        elif fields[0] == 'f':
            index = [int(f.split('/')[0]) for f in fields[1:]]
            index = [i - 1 if i > 0 else len(vertices) + i for i in index]
            triangles += [(index[0], index[k], index[k + 1]) for k in range(1, len(index) - 1)]
    camera = a.eye + a.look + a.up + [a.fov] + a.light + [0.0, 0.0, a.scale]
    with open(a.out, 'wb') as f:
        f.write(b'RTSC' + struct.pack('<II', len(vertices), len(triangles)) + struct.pack('<16f', *camera))
        for v in vertices:
            f.write(struct.pack('<3f', *v))
        for t in triangles:
            f.write(struct.pack('<3I', *t))
    print(f'{a.out}: {len(vertices)} vertices, {len(triangles)} triangles')


if __name__ == '__main__':
    main()
