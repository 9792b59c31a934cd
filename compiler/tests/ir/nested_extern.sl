// Nested functions reach enclosing variables through `extern`: they become by-reference parameters,
// passed by every call (also from a sibling nested function, which captures them in turn).
surface nested_extern(float freq = 4;)
{
    float scale = freq * 2;
    float stripes(float x)
    {
        extern float scale;
        return mod(x * scale, 1);
    }
    float twostripes(float x)
    {
        return stripes(x) * stripes(x + .5);
    }
    Ci = Cs * twostripes(s);
    Oi = Os;
}
