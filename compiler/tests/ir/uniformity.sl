// Uniform/varying inference: `k` stays uniform, `n` becomes varying through noise(P), `acc` becomes
// varying because it is assigned under a varying condition, and the helper's result is uniform for
// uniform arguments (it reads no varying state).
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
    Ci = Cs * (acc + depth);
    Oi = Os;
}
