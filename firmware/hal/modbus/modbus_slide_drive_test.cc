// The Modbus backend against the simulated drive (a real libmodbus server) over loopback
// TCP and over a pseudo-terminal (RTU). Assertions compare with the simulator's own
// state; waits poll for a condition with a generous deadline, so nothing depends on
// timing (the tests also run under qemu-aarch64).
#include "firmware/hal/modbus/modbus_slide_drive.h"

#include <chrono>
#include <functional>
#include <memory>
#include <ostream>
#include <string>
#include <thread>

#include <gtest/gtest.h>

#include "boards/virtual/drive_sim/drive_sim.h"

namespace mirrorscan::hal {
namespace {

using virtual_cabinet::DriveSim;
using virtual_cabinet::DriveSimConfig;
using virtual_cabinet::DriveSimState;
using Clock = std::chrono::steady_clock;
using std::chrono::milliseconds;
using std::chrono::seconds;

constexpr double kCountMm = 0.01;  // one position count at 100 counts/mm

const std::string kFixture =
    std::string(MIRRORSCAN_SOURCE_DIR) + "/firmware/hal/modbus/testdata/board_drive.json";

// The simulator serving the register map the backend is configured with.
DriveSimConfig SimConfigFor(const ModbusDriveConfig& c) {
  DriveSimConfig sim;
  sim.map = c.registers;
  sim.model.min_mm = c.travel_min_mm;
  sim.model.max_mm = c.travel_max_mm;
  sim.model.max_speed_mm_s = c.max_speed_mm_s;
  sim.model.homing_speed_mm_s = 400.0;
  sim.model.initial_position_mm = 60.0;  // homing takes 150 ms
  sim.slave_id = c.slave_id;
  return sim;
}

// Polls `condition` until it holds or a generous deadline passes.
bool Eventually(const std::function<bool()>& condition, Clock::duration deadline = seconds(10)) {
  const auto end = Clock::now() + deadline;
  while (!condition()) {
    if (Clock::now() > end) return false;
    std::this_thread::sleep_for(milliseconds(2));
  }
  return true;
}

HardwareError::Kind KindOf(const std::function<void()>& f, std::string* message = nullptr) {
  try {
    f();
  } catch (const HardwareError& e) {
    if (message) *message = e.what();
    return e.kind();
  }
  ADD_FAILURE() << "no HardwareError";
  return HardwareError::Kind::kIo;
}

struct Variant {
  std::string name;
  bool rtu;
  bool coils;           // control as coils (else a holding control word)
  bool low_word_first;  // position/target word order
  bool status_holding;  // status, fault code and position in holding registers
};

// Test names and ctest entries show the variant's name, not its bytes.
void PrintTo(const Variant& variant, std::ostream* out) { *out << variant.name; }

class ModbusSlideDriveTest : public ::testing::TestWithParam<Variant> {
 protected:
  void SetUp() override {
    config_ = LoadModbusDriveConfig(kFixture);
    const Variant& v = GetParam();
    config_.response_timeout_s = 0.5;  // generous for qemu; the timeout test shortens it
    if (v.coils) {
      config_.registers.control.table = ModbusTable::kCoils;
      config_.registers.control.address = 16;  // coils 16..20
    }
    if (v.low_word_first) config_.registers.position.word_order = WordOrder::kLowFirst;
    if (v.status_holding) {
      config_.registers.status.table = config_.registers.fault_code.table =
          config_.registers.position.table = ModbusTable::kHolding;
      config_.registers.status.address = 10;
      config_.registers.fault_code.address = 12;  // not adjacent: read separately
      config_.registers.position.address = 20;
    }
    StartSim();
  }

  void StartSim(double initial_position_mm = 60.0) {
    sim_.reset();
    DriveSimConfig sim_config = SimConfigFor(config_);
    sim_config.model.initial_position_mm = initial_position_mm;
    if (GetParam().rtu) {
      sim_ = DriveSim::ServeRtu(sim_config);
      config_.transport = ModbusDriveConfig::Transport::kRtu;
      config_.device = sim_->device();
    } else {
      sim_ = DriveSim::ServeTcp(sim_config);
      config_.transport = ModbusDriveConfig::Transport::kTcp;
      config_.host = "127.0.0.1";
      config_.port = sim_->port();
    }
  }

  std::unique_ptr<ModbusSlideDrive> Connect() {
    return std::make_unique<ModbusSlideDrive>(config_);
  }

  // Enabled and homed, at 0 mm.
  std::unique_ptr<ModbusSlideDrive> ReadyDrive() {
    auto drive = Connect();
    drive->Enable(true);
    drive->Home(seconds(10));
    return drive;
  }

  ModbusDriveConfig config_;
  std::unique_ptr<DriveSim> sim_;
};

TEST_P(ModbusSlideDriveTest, EnableHomeMoveAtTheSetSpeedAndStop) {
  auto drive = Connect();
  EXPECT_FALSE(drive->Status().enabled);
  EXPECT_NEAR(drive->Position(), 60.0, kCountMm);

  drive->Enable(true);
  EXPECT_TRUE(sim_->State().model.enabled);
  EXPECT_TRUE(drive->Status().enabled);

  drive->Home(seconds(10));
  DriveSimState s = sim_->State();
  EXPECT_TRUE(s.model.homed);
  EXPECT_EQ(s.model.position_mm, 0.0);
  EXPECT_TRUE(drive->Status().homed);
  EXPECT_EQ(drive->Position(), 0.0);

  drive->SetSpeed(123.4);
  EXPECT_NEAR(sim_->State().model.speed_mm_s, 123.4, 1e-9);

  drive->Start(1800.0);
  EXPECT_TRUE(sim_->State().model.moving);
  EXPECT_NEAR(sim_->State().model.goal_mm, 1800.0, 1e-9);
  ASSERT_TRUE(Eventually([&] { return sim_->State().model.position_mm > 20.0; }));
  const SlideStatus moving = drive->Status();
  EXPECT_TRUE(moving.moving);
  EXPECT_FALSE(moving.fault);

  // The readback lies between the simulator's positions just before and just after it.
  const DriveSimState before = sim_->State();
  const double readback = drive->Position();
  const DriveSimState after = sim_->State();
  EXPECT_GE(readback, before.model.position_mm - kCountMm);
  EXPECT_LE(readback, after.model.position_mm + kCountMm);
  EXPECT_GT(after.model.position_mm, before.model.position_mm);

  // The slide moves at the set speed: distance over the simulator's own clock.
  const DriveSimState a = sim_->State();
  ASSERT_TRUE(
      Eventually([&] { return sim_->State().model.time_ns > a.model.time_ns + 50'000'000; }));
  const DriveSimState b = sim_->State();
  ASSERT_TRUE(b.model.moving);
  const double speed = (b.model.position_mm - a.model.position_mm) /
                       (static_cast<double>(b.model.time_ns - a.model.time_ns) * 1e-9);
  EXPECT_NEAR(speed, 123.4, 1e-6);
  // And the readback keeps increasing.
  const double later = drive->Position();
  EXPECT_GT(later, readback);

  drive->Stop();
  const DriveSimState stopped = sim_->State();
  EXPECT_FALSE(stopped.model.moving);
  EXPECT_FALSE(drive->Status().moving);
  EXPECT_NEAR(drive->Position(), stopped.model.position_mm, kCountMm);
  EXPECT_EQ(sim_->State().model.position_mm, stopped.model.position_mm);

  drive->Enable(false);
  EXPECT_FALSE(sim_->State().model.enabled);
}

TEST_P(ModbusSlideDriveTest, MovesDownAndStopsAtTheTarget) {
  auto drive = ReadyDrive();
  drive->SetSpeed(500.0);
  drive->Start(300.0);
  ASSERT_TRUE(Eventually([&] { return !drive->Status().moving; }));
  EXPECT_EQ(sim_->State().model.position_mm, 300.0);
  EXPECT_NEAR(drive->Position(), 300.0, kCountMm);
  drive->Start(123.45);
  ASSERT_TRUE(Eventually([&] { return !drive->Status().moving; }));
  EXPECT_NEAR(sim_->State().model.position_mm, 123.45, 1e-9);
  EXPECT_NEAR(drive->Position(), 123.45, kCountMm);
}

TEST_P(ModbusSlideDriveTest, FaultMidMoveIsReportedWithItsCode) {
  auto drive = ReadyDrive();
  drive->SetSpeed(100.0);
  drive->Start(1500.0);
  ASSERT_TRUE(Eventually([&] { return sim_->State().model.position_mm > 5.0; }));
  sim_->InjectFault(0x2310);
  const SlideStatus status = drive->Status();
  EXPECT_TRUE(status.fault);
  EXPECT_EQ(status.fault_code, 0x2310);
  EXPECT_FALSE(status.moving);
  EXPECT_EQ(ToString(status), "enabled, homed, still, fault 8976");
  // A faulted drive ignores commands until the fault is reset.
  drive->Start(1000.0);
  EXPECT_FALSE(sim_->State().model.moving);
  drive->ResetFault();
  EXPECT_FALSE(drive->Status().fault);
  EXPECT_EQ(drive->Status().fault_code, 0);
  drive->Start(1000.0);
  EXPECT_TRUE(drive->Status().moving);
  drive->Stop();
}

TEST_P(ModbusSlideDriveTest, HomingFaultTimeoutAndStopAreErrors) {
  StartSim(1500.0);  // homing takes 3.75 s, far longer than the short timeout below
  auto drive = Connect();
  // Homing a disabled drive: the drive faults and Home() says so with the code.
  std::string message;
  EXPECT_EQ(KindOf([&] { drive->Home(seconds(10)); }, &message), HardwareError::Kind::kFault);
  EXPECT_EQ(message, "slide drive: fault 16 while homing");
  drive->ResetFault();
  drive->Enable(true);
  // A 20 ms timeout stops the drive.
  EXPECT_EQ(KindOf([&] { drive->Home(milliseconds(20)); }), HardwareError::Kind::kTimeout);
  EXPECT_FALSE(sim_->State().model.moving);
  EXPECT_FALSE(sim_->State().model.homed);
  // Stop() from another thread (the supervisor) interrupts Home().
  std::thread supervisor([&] {
    Eventually([&] { return sim_->State().model.moving; });
    drive->Stop();
  });
  EXPECT_EQ(KindOf([&] { drive->Home(seconds(10)); }), HardwareError::Kind::kAborted);
  supervisor.join();
  EXPECT_FALSE(sim_->State().model.moving);
}

TEST_P(ModbusSlideDriveTest, RefusesArgumentsOutsideTheLimitsWithoutSending) {
  auto drive = ReadyDrive();
  const uint64_t requests = sim_->State().requests;
  EXPECT_EQ(KindOf([&] { drive->SetSpeed(0.0); }), HardwareError::Kind::kInvalidArgument);
  EXPECT_EQ(KindOf([&] { drive->SetSpeed(501.0); }), HardwareError::Kind::kInvalidArgument);
  EXPECT_EQ(KindOf([&] { drive->Start(1900.5); }), HardwareError::Kind::kInvalidArgument);
  EXPECT_EQ(KindOf([&] { drive->Start(-1.0); }), HardwareError::Kind::kInvalidArgument);
  EXPECT_EQ(sim_->State().requests, requests);
}

TEST_P(ModbusSlideDriveTest, SilentDriveTimesOutWithinTheBoundThenRecovers) {
  config_.response_timeout_s = 0.2;
  config_.retries = 2;
  auto drive = Connect();
  drive->Enable(true);
  sim_->SetResponding(false);
  const uint64_t requests = sim_->State().requests;
  const auto start = Clock::now();
  std::string message;
  EXPECT_EQ(KindOf([&] { drive->Status(); }, &message), HardwareError::Kind::kTimeout);
  const double elapsed = std::chrono::duration<double>(Clock::now() - start).count();
  EXPECT_NE(message.find("3 attempts, response timeout 0.2 s"), std::string::npos) << message;
  EXPECT_GE(elapsed, 3 * 0.2 * 0.9);                // it really waited for each attempt
  EXPECT_LE(elapsed, 3 * 0.2 + 1.5);                // and no longer than the bound (+ slack)
  EXPECT_EQ(sim_->State().requests, requests + 3);  // 1 + retries, each seen by the drive
  // The supervisor's Stop() is bounded the same way.
  EXPECT_EQ(KindOf([&] { drive->Stop(); }), HardwareError::Kind::kTimeout);
  sim_->SetResponding(true);
  EXPECT_TRUE(drive->Status().enabled);
}

TEST_P(ModbusSlideDriveTest, ModbusExceptionIsRejectedWithoutRetries) {
  config_.registers.fault_code.address = 500;  // the drive has no such register
  config_.registers.status.address = 400;
  auto drive = Connect();
  const uint64_t requests = sim_->State().requests;
  std::string message;
  EXPECT_EQ(KindOf([&] { drive->Status(); }, &message), HardwareError::Kind::kRejected);
  EXPECT_NE(message.find("read status"), std::string::npos) << message;
  EXPECT_EQ(sim_->State().requests, requests + 1);
}

TEST_P(ModbusSlideDriveTest, ReconnectsAfterTheLinkDrops) {
  auto drive = Connect();
  drive->Enable(true);
  sim_->DropConnection();
  EXPECT_TRUE(drive->Status().enabled);
  EXPECT_NEAR(drive->Position(), 60.0, kCountMm);
}

TEST_P(ModbusSlideDriveTest, MissingDriveFailsToOpen) {
  const bool rtu = GetParam().rtu;
  sim_.reset();  // the port is closed, or the pty gone
  if (rtu) config_.device = "/nonexistent/ttyMODBUS";
  config_.response_timeout_s = 0.2;
  const auto start = Clock::now();
  std::string message;
  EXPECT_EQ(KindOf([&] { Connect(); }, &message), HardwareError::Kind::kIo);
  EXPECT_LE(std::chrono::duration<double>(Clock::now() - start).count(), 3 * 0.2 + 1.5);
  EXPECT_NE(message.find("cannot connect"), std::string::npos) << message;
}

INSTANTIATE_TEST_SUITE_P(
    Links, ModbusSlideDriveTest,
    ::testing::Values(Variant{"Tcp", false, false, false, false},
                      Variant{"TcpCoilsLowWordFirstHolding", false, true, true, true},
                      Variant{"Rtu", true, false, false, false},
                      Variant{"RtuCoilsLowWordFirstHolding", true, true, true, true}),
    [](const auto& test) { return test.param.name; });

}  // namespace
}  // namespace mirrorscan::hal
