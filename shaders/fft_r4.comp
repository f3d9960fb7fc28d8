#version 450
// Radix-4 pass of the Stockham FFT (see fft_common.glsl, kernels/fft.cpp).
#define RADIX 4
#include "fft_common.glsl"
