#version 450
// Radix-32 pass of the Stockham FFT (see fft_common.glsl, kernels/fft.cpp).
#define RADIX 32
#include "fft_common.glsl"
