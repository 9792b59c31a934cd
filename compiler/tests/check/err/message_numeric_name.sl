// expect: E0135
// The first argument of the message-passing function surface() must be a
// string naming the parameter, not a number.
light message_numeric_name(float intensity = 1; point from = point "shader" (0, 0, 0);)
{
    float kd = 1;
    surface(1, kd);
    illuminate(from) {
        Cl = intensity * kd;
    }
}
