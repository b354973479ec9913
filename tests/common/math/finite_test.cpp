// finite3 on an Eigen vector and on a wire Vec3: false as soon as one
// component is NaN or infinite.
#include "common/math/finite.h"

#include <limits>

#include <Eigen/Core>
#include <gtest/gtest.h>

#include "types.pb.h"

namespace hm = hemm::math;

TEST(Finite3, EveryComponentIsChecked) {
  const double bad[] = {std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity(),
                        -std::numeric_limits<double>::infinity()};
  EXPECT_TRUE(hm::finite3(Eigen::Vector3d(1.0, -2.0, 1e308)));
  hemm::proto::Vec3 w;
  w.set_x(1.0);
  w.set_y(-2.0);
  w.set_z(1e308);
  EXPECT_TRUE(hm::finite3(w));
  for (int i = 0; i < 3; ++i) {
    for (const double b : bad) {
      Eigen::Vector3d e(1.0, -2.0, 3.0);
      e[i] = b;
      EXPECT_FALSE(hm::finite3(e)) << i;
      hemm::proto::Vec3 v;
      v.set_x(i == 0 ? b : 1.0);
      v.set_y(i == 1 ? b : -2.0);
      v.set_z(i == 2 ? b : 3.0);
      EXPECT_FALSE(hm::finite3(v)) << i;
    }
  }
}
