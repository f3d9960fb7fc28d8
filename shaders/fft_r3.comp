#version 450
// Radix-3 pass of the Stockham FFT (see fft_common.glsl, kernels/fft.cpp).
#define RADIX 3
#include "fft_common.glsl"
