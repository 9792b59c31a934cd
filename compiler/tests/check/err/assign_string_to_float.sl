// expect: E0103
// A string value cannot be assigned to a float variable.
surface assign_string_to_float()
{
    float gain = "bright";
    Ci = Cs * gain;
    Oi = Os;
}
