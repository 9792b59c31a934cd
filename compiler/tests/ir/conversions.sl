// Implicit conversions become explicit nodes: float to color, point - point to vector, a relation
// to float, a space cast, and context-typed noise.
surface conversions()
{
    color c = 1;
    vector d = P - point "world" (0, 0, 0);
    float inside = s > .5;
    color n = noise(P * 4);
    Ci = c * n * inside * length(d);
    Oi = Os;
}
