// The main() of every test binary (imca_test): the load-time environment of
// our binaries (common/base/load_time_env.h), then GoogleTest.
#include "common/base/load_time_env.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

int main(int argc, char** argv) {
  imca::UseOurLoadTimeEnv(argv);
  ::testing::InitGoogleMock(&argc, argv);
  return RUN_ALL_TESTS();
}
