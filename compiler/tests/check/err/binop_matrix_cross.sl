// expect: E0106
// The cross-product operator ^ is defined only between point-like types,
// not between a matrix and a float.
surface binop_matrix_cross()
{
    matrix m = matrix "world" 1;
    Ci = Cs * determinant(m ^ 1.0);
    Oi = Os;
}
