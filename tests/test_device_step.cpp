// The device step (backend/device_step.hpp) run by its host emulation against the CPU engine:
// the GPU's logic, bit for bit, tested on every machine (tests/device_checks.hpp; on a GPU,
// tests/cuda/test_device.cpp runs the same checks and compares the bits).
#include "device_checks.hpp"
#include "helpers.hpp"

namespace crushdem {
namespace {

using device_checks::Check;

const device_checks::ApiFactory kEmulated = [] { return device::make_emulated_api(); };

void expect_all(const std::vector<Check>& checks) {
  ASSERT_FALSE(checks.empty());
  for (const Check& c : checks) {
    EXPECT_TRUE(c.ok) << c.name << ": " << c.detail;
    std::printf("  %s: %s\n", c.name.c_str(), c.detail.c_str());
  }
}

const Simulation& sample() {
  static const Simulation s = device_checks::compressed_sample();
  return s;
}

Simulation fixed_step_sample() {
  Simulation s = sample();
  s.set_dt(s.dt());
  return s;
}

TEST(DeviceStep, HeadOnImpactFollowsTheCpu) {
  expect_all(device_checks::impact(kEmulated));
}

TEST(DeviceStep, HistoryGoesThroughRebuilds) {
  expect_all(device_checks::rebuild_history(kEmulated, 0.0));
  expect_all(device_checks::rebuild_history(kEmulated, 0.2));
}

TEST(DeviceStep, BodiesOfAnyShapeFollowTheCpu) {
  expect_all(device_checks::bodies(kEmulated));
}

TEST(DeviceStep, AChamberSampleFollowsTheCpu) {
  expect_all(device_checks::chamber_sample(kEmulated));
}

TEST(DeviceStep, DenseSampleAgreesWithTheCpuAndRepeats) {
  expect_all(
      device_checks::compare_runs("fixed step", fixed_step_sample(), 2000, kEmulated, false));
  expect_all(device_checks::compare_runs("automatic step", sample(), 2000, kEmulated, false));
  Simulation moving = fixed_step_sample();
  moving.walls().config(3).mode = WallMode::Velocity;
  moving.walls().config(3).velocity = -1.0;
  expect_all(device_checks::compare_runs("moving wall", moving, 2000, kEmulated, true));
}

TEST(DeviceStep, ContactLoadEqualsTheCpus) {
  expect_all(device_checks::compare_load(fixed_step_sample(), 2000, kEmulated));
}

TEST(DeviceStep, HostChangesReachTheDevice) {
  expect_all(device_checks::host_changes(fixed_step_sample(), kEmulated));
}

TEST(DeviceStep, CrushingOnTheDeviceBreaksTheGrainsTheCpuBreaks) {
  expect_all(device_checks::crushing(fixed_step_sample(), kEmulated));
}

TEST(DeviceStep, ControllersScalarsAreReducedOnTheDevice) {
  expect_all(device_checks::inspection(kEmulated));
}

TEST(DeviceStep, TheTimeStepsContactTermIsReducedOnTheDevice) {
  expect_all(device_checks::stiffness_time(kEmulated));
}

TEST(DeviceStep, NonFinitePositionIsReportedByGrain) {
  expect_all(device_checks::nan_rule(fixed_step_sample(), kEmulated));
}

}  // namespace
}  // namespace crushdem
