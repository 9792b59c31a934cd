// Uniform/varying inference: `k` stays uniform, `n` becomes varying through noise(P), `acc` becomes
// varying because it is assigned under a varying condition, and the helper's result is uniform for
// uniform arguments (it reads no varying state). In the loop, `carried` reads `later` before the
// iteration makes `later` varying, so both end varying (the value reaches the next iteration), and
// `before` is assigned ahead of a divergent `break`, which makes it varying from the second
// iteration on; `count` turns varying too, since only the lanes still looping step it. A divergent
// `break 2` in an inner loop leaves the outer loop too: `row`, stepped by the outer loop, turns
// varying, while the inner counter `col` (reset every outer iteration) was varying anyway.
float twice(float x) { return 2 * x; }

surface uniformity(float Kd = .5; string mapname = "";)
{
    float k = twice(Kd);
    float n = noise(P);
    float acc = 0;
    if (n > .5) {
        acc = k;
    }
    uniform float depth = 0;
    rayinfo("depth", depth);
    float carried = 0, later = 0, before = 0, count = 0;
    for (count = 0; count < 3; count += 1) {
        before = count;
        carried = later;
        later = s;
        if (n > .9) {
            break;
        }
    }
    float row, col, found = 0;
    for (row = 0; row < 3; row += 1) {
        for (col = 0; col < 3; col += 1) {
            if (s > col / 3) {
                found = row;
                break 2;
            }
        }
    }
    Ci = Cs * (acc + depth + carried + before + found);
    Oi = Os;
}
