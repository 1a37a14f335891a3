// color.glsl — constants shared by shading code.
#ifndef COLOR_GLSL
#define COLOR_GLSL

const float PI = 3.14159265358979323846;
const float INV_PI = 0.31830988618379067154;

#endif
