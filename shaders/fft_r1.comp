#version 450
// Radix-1 pass of the Stockham FFT (see fft_common.glsl, kernels/fft.cpp).
#define RADIX 1
#include "fft_common.glsl"
