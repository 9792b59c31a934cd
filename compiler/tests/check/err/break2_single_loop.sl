// expect: E0113
// "break 2" asks to leave two enclosing loops, but only one loop encloses
// it.
surface break2_single_loop(float steps = 8;)
{
    float i, sum = 0;
    for (i = 0; i < steps; i += 1) {
        sum += noise(P * (i + 1));
        if (sum > 2)
            break 2;
    }
    Ci = Cs * sum / steps;
    Oi = Os;
}
