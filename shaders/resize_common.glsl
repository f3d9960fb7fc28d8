// Shared by resize.comp and resize_into_padded.comp: the taps of the resize
// modes (kernels/resize.hpp, ResizeMode).
#ifndef VKJR2_RESIZE_COMMON_GLSL
#define VKJR2_RESIZE_COMMON_GLSL

// Taps of output coordinate d on one axis of n_in input pixels:
// value = (1 - l)·in[i0] + l·in[i1] (nearest, mode 3: i1 = i0, l = 0).
void resize_taps(uint mode, int d, int n_in, float scale, out int i0, out int i1, out float l) {
  precise float s;
  if (mode == 0u) {
    s = (float(d) + 0.5) * scale - 0.5;
  } else {
    s = float(d) * scale;
  }
  s = clamp(s, 0.0, float(n_in - 1));
  i0 = min(int(s), n_in - 1);
  if (mode == 3u) {
    i1 = i0;
    l = 0.0;
  } else {
    i1 = min(i0 + 1, n_in - 1);
    l = s - float(i0);
  }
}

#endif
