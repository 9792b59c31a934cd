// expect: E0109
// The texture coordinate s is a read-only global in a surface shader.
surface write_readonly_s(float repeats = 4;)
{
    s = mod(s * repeats, 1);
    Ci = color(s, t, 0);
    Oi = Os;
}
