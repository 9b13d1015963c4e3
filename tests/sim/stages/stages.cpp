// Single stages of the kernel, driven from tests/sim/test_stages.py: each command reads numbers on
// stdin and prints its results, one per line (%.17g), in plain double (the scalar form).
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "../../../sanlab/sim/_kernel/step.h"

using namespace sanlab;

static double next() {
  double x;
  if (std::scanf("%lf", &x) != 1) std::exit(2);
  return x;
}

int main(int argc, char **argv) {
  if (argc < 2) return 2;
  const char *cmd = argv[1];
  if (!std::strcmp(cmd, "stick_slip")) {  // stretch v limit gk slip h -> coef f held
    double a[6];
    for (double &x : a) x = next();
    double coef, f, held;
    stick_slip(a[0], a[1], a[2], a[3], a[4], a[5], coef, f, held);
    std::printf("%.17g\n%.17g\n%.17g\n", coef, f, held);
  } else if (!std::strcmp(cmd, "terrain")) {  // kind slope H hw c K (a w ph)*K n x*n -> (h dh)*n
    int32_t wi[WI_WIDTH] = {};
    double wf[WF_WIDTH] = {};
    wi[0] = (int)next();  // WorldInts.terrain
    WorldNumbers<double> &w = *(WorldNumbers<double> *)wf;
    w.slope = next();
    w.hill_height = next();
    w.hill_half_width = next();
    w.hill_centre = next();
    Model m{};
    m.wi = wi;
    m.nrough = (int)next();
    std::vector<double> rough(3 * m.nrough);
    for (double &x : rough) x = next();
    Tile<double> t{};
    t.wf = wf;
    t.rough = rough.data();
    int n = (int)next();
    for (int k = 0; k < n; ++k) {
      double h, dh;
      terrain(m, t, next(), h, dh);
      std::printf("%.17g\n%.17g\n", h, dh);
    }
  } else if (!std::strcmp(cmd, "solve")) {  // D, A (D x D, row-major), b (D) -> x
    int D = (int)next();
    std::vector<double> A(D * D), b(D), x(D), F(D * D), Lf(D * D);
    for (double &v : A) v = next();
    for (double &v : b) v = next();
    Tile<double> t{};
    t.F = F.data();
    t.Lf = Lf.data();
    solve(t, A.data(), b.data(), x.data(), D);
    for (double v : x) std::printf("%.17g\n", v);
  } else {
    return 2;
  }
  return 0;
}
