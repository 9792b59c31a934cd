/*
 * tonemap.sl -- rtsl's standard pixel shaders: "tonemap".
 *
 * Maps unbounded linear light into [0, 1) for display.  Two curves:
 *   "reinhard" -- Reinhard et al. 2002, extended: c (1 + c / w^2) / (1 + c),
 *                 so that the white point w maps to 1;
 *   "filmic"   -- John Hable's filmic curve (Uncharted 2), with a toe and a
 *                 shoulder, normalised so that the white point maps to 1.
 * Each colour component is mapped on its own, after scaling by exposure.
 *
 * Parameters:
 *   curve      -- "reinhard" or "filmic" ("reinhard").
 *   exposure   -- linear scale applied first (1).
 *   whitepoint -- the input level that maps to white (4).
 */
float hable(float x;)
{
    float A = 0.15, B = 0.50, C = 0.10, D = 0.20, E = 0.02, F = 0.30;
    return ((x * (A * x + C * B) + D * E) / (x * (A * x + B) + D * F)) - E / F;
}

float curve1(float x; string curve; float w;)
{
    float c = max(x, 0);
    float r;
    if (curve == "filmic")
        r = hable(2 * c) / hable(w);
    else
        r = c * (1 + c / (w * w)) / (1 + c);
    return r;
}

pixel tonemap(string curve = "reinhard"; float exposure = 1; float whitepoint = 4;)
{
    color c = Ci * exposure;
    Ci = color(curve1(comp(c, 0), curve, whitepoint),
               curve1(comp(c, 1), curve, whitepoint),
               curve1(comp(c, 2), curve, whitepoint));
}
