/* A host program built against an installed vfe: cc -std=c99 host.c -I P/include -L P/lib -lvfe -Wl,-rpath,P/lib */
#include <vfe/vfe.h>

#include <stdio.h>

int main(void) {
  const double origin[3] = {0, 0, 0}, spacing[3] = {1, 1, 1};
  const int64_t cells[3] = {2, 2, 2};
  const double centre[3] = {1, 1, 1}, radius = 0.5;
  double solid[8], total = 0;
  vfe_engine* e = NULL;
  int c;
  if (vfe_create_cartesian(origin, spacing, cells, &e) != VFE_OK) {
    fprintf(stderr, "host: %s\n", vfe_last_error(NULL));
    return 1;
  }
  if (vfe_configure(e, "method=exact") != VFE_OK || vfe_compute(e, 1, centre, &radius, NULL, solid) != VFE_OK) {
    fprintf(stderr, "host: %s\n", vfe_last_error(e));
    vfe_destroy(e);
    return 1;
  }
  for (c = 0; c < 8; ++c) total += solid[c];
  printf("vfe %s: solid volume %.12f (sphere %.12f)\n", vfe_version(), total, 4.0 / 3.0 * 3.14159265358979 * 0.125);
  vfe_destroy(e);
  return total > 0.5235 && total < 0.5236 ? 0 : 1;
}
