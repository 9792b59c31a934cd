// expect: E0127
// A string cannot be typecast to a matrix, even with a space name.
surface cast_matrix_string()
{
    matrix m = matrix "world" "hi";
    Ci = Cs * determinant(m);
    Oi = Os;
}
