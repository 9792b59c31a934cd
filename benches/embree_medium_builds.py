#!/usr/bin/env python3
"""Compares rtsl's build time with Embree's medium-quality build, from the log that
../shared/bench/embree/side-by-side.sh writes (its summary table compares with Embree's fastest
build of any quality instead):

    PAIRS=3 REPS=3 bash ../shared/bench/embree/side-by-side.sh target/release/rtsl
    python3 benches/embree_medium_builds.py /tmp/rtsl-vs-embree/log.txt

Prints, per scene and thread count, the median of Embree's medium builds over the median of
rtsl's builds (above 1: rtsl builds faster), with both lists of times in milliseconds.
"""
import re
import statistics
import sys


def main(path):
    log = open(path).read()
    embree = {}
    for m in re.finditer(r'ROW\|embree\|(\w+)\.bin\|medium\|build\|(\d+)\|([\d.]+)', log):
        embree.setdefault((m.group(1), int(m.group(2))), []).append(float(m.group(3)))
    rtsl = {}
    for block in log.split('### ')[1:]:
        head = re.match(r'rtsl (\w+) threads=(\d+)', block)
        build = re.search(r'build_ms: ([\d.]+)', block)
        if head and build:
            rtsl.setdefault((head.group(1), int(head.group(2))), []).append(float(build.group(1)))
    if not rtsl:
        sys.exit(f'{path}: no rtsl builds found (is it a side-by-side.sh log?)')
    print('scene    threads  embree medium / rtsl  (embree ms; rtsl ms)')
    for key in sorted(rtsl):
        if key not in embree:
            print(f'{key[0]:8} {key[1]:7}  no Embree medium builds in the log')
            continue
        ratio = statistics.median(embree[key]) / statistics.median(rtsl[key])
        print(f'{key[0]:8} {key[1]:7}  {ratio:.2f}  ({embree[key]}; {rtsl[key]})')


if __name__ == '__main__':
    if len(sys.argv) != 2:
        sys.exit('usage: embree_medium_builds.py LOG')
    main(sys.argv[1])
