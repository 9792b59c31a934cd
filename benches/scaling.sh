#!/usr/bin/env bash
# Thread and MPI scaling on a many-core machine (the figures of docs/distributed.md, the thread
# scaling and Embree tables of docs/tracer.md, and the GI rates of docs/global_illumination.md).
#
#   benches/scaling.sh pack          # here: a stripped release build with MPI, the scenes and
#                                    # Embree's benchmark, into .scaling/ (keep it out of git)
#   benches/scaling.sh run [PARTS]   # there: PARTS of "mpi threads bandwidth forest latency
#                                    # copies quarters spin ahead thp gi embree" (default: all but
#                                    # threads, which mpi's runs include, copies, quarters, spin,
#                                    # ahead and thp)
#
# `run` needs only what `pack` made: the machine's `mpirun` (Open MPI 4.x: the binary links
# libmpi.so.40), else the Open MPI that `pack` took from this machine. It prints what each
# command reports and keeps going past failures. `mpi` runs master + N workers of one thread,
# then one process of N threads, for each N of WORKERS (default "1 2 4 8 15"), then one process
# on every core; `threads` runs one process over THREADS (default "1 2 4 8 16"); `forest` runs
# examples/forest over 2 workers and over a worker a core but the master's (what each fetches);
# `latency` runs the BART animations over a worker rank a core but the master's, each with one
# and then two render threads (the second renders while the first waits for a fetch); `copies`
# runs the BART kitchen and robots and the office over a worker rank a core but the master's,
# with tile copies at a frame's end and with `--no-tile-copies`, twice, interleaved; `quarters`
# the same with the last tiles of a frame in quarters and with `--no-tile-quarters`; `spin` the
# BART animations the same way with and without `--master-spins`, `ahead` with and without
# `--no-asking-ahead`, and `thp` (with Sponza) with transparent huge pages off, the default of ranks, and
# on (`MIMALLOC_ALLOW_THP=1` in every rank); `embree`
# runs ../shared/bench/embree/side-by-side.sh on 1 thread and every core (EMBREE_SCENES: its
# scenes; EMBREE_THREADS: its thread counts). DEADLINE: seconds after which no new command starts
# (default 500); COMMAND_LIMIT: seconds one command may take (default 120); EMBREE_LIMIT: seconds
# for the embree part (its raw log stays in /tmp/rtsl-scaling/embree/log.txt);
# FULL_LOG: a file that gets every command's whole output.
set -u
HERE=$(cd "$(dirname "$0")/.." && pwd)
PACK=$HERE/.scaling

pack() {
  set -e
  cd "$HERE"
  cargo build --release --features mpi
  mkdir -p "$PACK"
  strip -o "$PACK/rtsl" target/release/rtsl
  tar -C "$HERE/.." -cJf "$PACK/scenes.tar.xz" shared/scenes/bart/robot shared/scenes/bart/kitchen \
    shared/scenes/sponza_dabrovic shared/scenes/cornell_box
  tar -C "$HERE/.." -cJf "$PACK/forest.tar.xz" shared/scenes/oak_tree \
    shared/scenes/stanford_dragon/dragon_vrip.ply shared/scenes/mountain_terrain
  if [ -f /usr/include/embree3/rtcore.h ]; then
    local e; e=$(mktemp -d)
    mkdir -p "$e/embree/lib"
    g++ -O3 -march=x86-64-v3 -ffp-contract=off -std=c++17 "$HERE/../shared/bench/embree/embree_bench.cpp" \
      -o "$e/embree/embree_bench" -lembree3 -lpthread
    rustc -O -o "$e/embree/gen_scene" "$HERE/../shared/bench/gen_scene.rs"
    cp -L "$(ldconfig -p | awk '/libembree3.so.3 /{print $NF; exit}')" \
      "$(ldconfig -p | awk '/libtbb.so.12 /{print $NF; exit}')" "$e/embree/lib/"
    # The side-by-side script without its build steps: it runs the binaries made here.
    sed -e '/^if \[ ! -f \/usr\/include/,/^fi$/d' -e '/^g++ /d' -e '/^rustc /d' \
      "$HERE/../shared/bench/embree/side-by-side.sh" > "$e/embree/side.sh"
    tar -C "$e" -cJf "$PACK/embree.tar.xz" embree
    rm -rf "$e"
  else
    echo "no Embree headers (apt-get install libembree-dev): the embree part will be skipped"
  fi
  pack_open_mpi
  du -sh "$PACK"
}

# Debian's Open MPI with the libraries it and its plugins load, for a machine without MPI: `run`
# unpacks it and runs it relocated (OPAL_PREFIX) when the machine's own mpirun is missing or fails.
pack_open_mpi() {
  local d; d=$(mktemp -d)/ompi
  mkdir -p "$d/usr/bin" "$d/usr/lib/x86_64-linux-gnu" "$d/usr/share" "$d/deps"
  cp -a /usr/lib/x86_64-linux-gnu/openmpi /usr/lib/x86_64-linux-gnu/pmix2 "$d/usr/lib/x86_64-linux-gnu/"
  rm -rf "$d/usr/lib/x86_64-linux-gnu/openmpi/include" "$d/usr/lib/x86_64-linux-gnu/pmix2/include"
  cp -a /usr/share/openmpi "$d/usr/share/"
  for b in orterun orted ompi_info; do cp -L "/usr/bin/$b" "$d/usr/bin/"; done
  ln -s orterun "$d/usr/bin/mpirun"
  find "$d/usr" "$PACK/rtsl" -type f \( -name '*.so*' -o -perm -u+x \) -exec ldd {} \; 2>/dev/null |
    awk '/=> \//{print $3}' | sort -u |
    grep -vE '/(libc|libm|libpthread|libdl|librt|ld-linux-x86-64|libstdc\+\+|libgcc_s|libutil)\.so|/openmpi/' |
    xargs -r cp -L -t "$d/deps/"
  tar -C "$(dirname "$d")" -cJf "$PACK/ompi.tar.xz" ompi
  rm -rf "$(dirname "$d")"
}

# Uses the packed Open MPI, with the settings Debian keeps in /etc/openmpi.
use_packed_open_mpi() {
  mkdir -p /tmp/rtsl-ompi && tar -C /tmp/rtsl-ompi -xJf "$PACK/ompi.tar.xz"
  local d=/tmp/rtsl-ompi/ompi
  export PATH=$d/usr/bin:$PATH OPAL_PREFIX=$d/usr PMIX_INSTALL_PREFIX=$d/usr/lib/x86_64-linux-gnu/pmix2
  export LD_LIBRARY_PATH=$d/deps:$d/usr/lib/x86_64-linux-gnu/openmpi/lib:$d/usr/lib/x86_64-linux-gnu/pmix2/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}
  export OMPI_MCA_btl_base_warn_component_unused=0 OMPI_MCA_mtl=^ofi OMPI_MCA_btl=^uct,openib,ofi \
    OMPI_MCA_pml=^ucx OMPI_MCA_osc=^ucx,pt2pt
}

run() {
  local parts=${*:-mpi bandwidth forest latency gi embree}
  local r=$PACK/rtsl b=/tmp/rtsl-scaling
  mkdir -p "$b"
  tar -C "$b" -xJf "$PACK/scenes.tar.xz"
  [ -f "$PACK/forest.tar.xz" ] && tar -C "$b" -xJf "$PACK/forest.tar.xz"
  [ -f "$PACK/embree.tar.xz" ] && tar -C "$b" -xJf "$PACK/embree.tar.xz"
  [ -e "$HERE/../shared" ] || ln -s "$b/shared" "$HERE/../shared"
  cd "$HERE"
  export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
  local check="timeout 60 mpirun -n 3 --oversubscribe --bind-to none $r bench render --size 160x120 --frames 3 --threads 1 --mpi"
  if ! $check > /dev/null 2>&1 && [ -f "$PACK/ompi.tar.xz" ]; then
    echo "the machine's MPI fails or is missing: using the packed Open MPI"
    use_packed_open_mpi
    $check > /dev/null 2>&1 || echo "the packed Open MPI fails too"
  fi
  local m="mpirun --bind-to none --oversubscribe"
  local workers=${WORKERS:-1 2 4 8 15} threads=${THREADS:-1 2 4 8 16}
  local robot=../shared/scenes/bart/robot/aff/Robot.aff kitchen=../shared/scenes/bart/kitchen/aff/kitchen.aff
  local t0; t0=$(date +%s)
  echo "machine: $(nproc) cpus,$(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2), $(mpirun --version 2>&1 | head -1)"
  one() {
    if [ $(($(date +%s) - t0)) -gt "${DEADLINE:-500}" ]; then echo "skipped (deadline): $*"; return; fi
    echo "### $*"
    timeout "${COMMAND_LIMIT:-120}" "$@" > /tmp/rtsl-scaling.log 2>&1
    local rc=$?
    [ -n "${FULL_LOG:-}" ] && { echo "### $*"; cat /tmp/rtsl-scaling.log; } >> "$FULL_LOG"
    grep -E "^fps|^tiles: |frames: |MPI traffic|worker time|demand loading|worker ranks" /tmp/rtsl-scaling.log | sed -E 's/ update .*//' | cut -c1-800
    [ $rc -ne 0 ] && { echo "exit status $rc"; tail -4 /tmp/rtsl-scaling.log; }
  }
  scenes() {  # $1: threads, then any prefix (mpirun) and flags
    local n=$1; shift; local pre=$1; shift
    one $pre $r bench render --threads "$n" --size 640x480 --frames 10 "$@"
    one $pre $r bart $robot --frames 20 --size 640x480 --threads "$n" -q "$@"
    one $pre $r bench render examples/scenes/sponza.rib --threads "$n" --frames 10 "$@"
    one $pre $r bart $kitchen --frames 10 --size 640x480 --threads "$n" -q "$@"
  }
  # The scenes named after $1 and $2 over a worker rank a core but the master's, with flag $1
  # and then flag $2 ("" for none), twice, interleaved (A B A B). A flag NAME=VALUE is set in
  # every rank's environment instead.
  interleaved() {
    local a=$1 b=$2; shift 2
    for pass in 1 2; do
      for flag in "$a" "$b"; do
        local pre=(env) opt=$flag mn=(-n "$(nproc)")
        if [[ $flag == *=* ]]; then pre=(env "$flag"); opt=""; mn=(-x "${flag%%=*}" -n "$(nproc)"); fi
        for scene in "$@"; do
          case $scene in
            kitchen) one "${pre[@]}" $m "${mn[@]}" $r bart $kitchen --frames 10 --size 640x480 --threads 1 -q --mpi $opt ;;
            robots) one "${pre[@]}" $m "${mn[@]}" $r bart $robot --frames 20 --size 640x480 --threads 1 -q --mpi $opt ;;
            office) one "${pre[@]}" $m "${mn[@]}" $r bench render --threads 1 --size 640x480 --frames 10 --mpi $opt ;;
            sponza) one "${pre[@]}" $m "${mn[@]}" $r bench render examples/scenes/sponza.rib --threads 1 --frames 10 --mpi $opt ;;
          esac
        done
      done
    done
  }
  for part in $parts; do
    echo "==== $part"
    case $part in
      threads) for n in $threads; do scenes "$n" ""; done ;;
      mpi)
        for n in $workers; do scenes 1 "$m -n $((n + 1))" --mpi; scenes "$n" ""; done
        scenes "$(nproc)" "" ;;
      bandwidth)
        printf 'Format 640 480 1\nProjection "perspective" "fov" 40\nTranslate 0 0 5\nWorldBegin\nSurface "constant"\nPolygon "P" [-1 -1 0  1 -1 0  1 1 0  -1 1 0]\nWorldEnd\n' > /tmp/trivial.rib
        one $r bench render /tmp/trivial.rib --threads "$(nproc)" --frames 20
        one $m -n "$(nproc)" $r bench render /tmp/trivial.rib --threads 1 --frames 20 --mpi ;;
      forest)
        # Demand loading of a scene of instanced trees: what each worker fetches of it.
        one $r bench render examples/forest/forest.rib --threads "$(nproc)" --frames 3
        for n in 2 "$(($(nproc) - 1))"; do
          one $m -n $((n + 1)) $r bench render examples/forest/forest.rib --threads 1 --frames 3 --mpi
        done ;;
      latency)
        for t in 1 2; do
          one $m -n "$(nproc)" $r bart $robot --frames 20 --size 640x480 --threads "$t" -q --mpi
          one $m -n "$(nproc)" $r bart $kitchen --frames 10 --size 640x480 --threads "$t" -q --mpi
        done ;;
      copies)
        # Tile copies for idle workers at a frame's end.
        interleaved "" --no-tile-copies kitchen robots office ;;
      quarters)
        # The last tiles of a frame handed out in quarters.
        interleaved "" --no-tile-quarters kitchen robots office ;;
      ahead)
        # Workers' tiles asking ahead for what they reach, set aside meanwhile.
        interleaved "" --no-asking-ahead robots kitchen ;;
      thp)
        # Transparent huge pages off (the default of ranks) and on, as mimalloc would have them.
        interleaved "" MIMALLOC_ALLOW_THP=1 robots kitchen sponza ;;
      spin)
        # The master polling without napping (it has a core of its own here).
        interleaved --master-spins "" robots kitchen ;;
      gi)
        for n in 2 "$(nproc)"; do
          one $r bench render examples/office/office_gi.rib --threads "$n" --frames 10
          one $r bench render examples/scenes/cornell_gi.rib --threads "$n" --frames 10
        done
        one $m -n "$(nproc)" $r bench render examples/office/office_gi.rib --threads 1 --frames 10 --mpi ;;
      embree)
        if [ -f "$b/embree/side.sh" ]; then
          (cd "$b/embree" && LD_LIBRARY_PATH=$b/embree/lib WORK=$b/embree PAIRS=1 REPS=3 \
            THREADS="${EMBREE_THREADS:-1,$(nproc)}" timeout "${EMBREE_LIMIT:-400}" bash ./side.sh "$r" ${EMBREE_SCENES:+"$EMBREE_SCENES"})
        else
          echo "not packed"
        fi ;;
      *) echo "unknown part $part" ;;
    esac
  done
  echo "done in $(($(date +%s) - t0)) s"
}

case ${1:-} in
  pack) pack ;;
  run) shift; run "$@" ;;
  *) sed -n '2,15p' "$0"; exit 2 ;;
esac
