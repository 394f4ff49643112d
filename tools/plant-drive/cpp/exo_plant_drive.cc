// exo_plant_drive: KickCAT's emulated EtherCAT bus with one CiA 402 drive whose
// mechanics are our plant (the SEA, the arm and the simulated human of
// exo-plant-sim, stepped through the C ABI of tools/plant-drive/src/lib.rs).
//
// What is KickCAT's and what is ours:
// - KickCAT (vendored, unchanged): the ESC (registers, SyncManagers, FMMUs, AL
//   state machine, SII and object dictionary compiled from the vendor's ESI),
//   the network that routes frames through it, and the drive's CiA 402 state
//   machine (its Ds402Motor, which this program keeps and runs every frame).
// - Ours: the device behaviour below (ExoPlantDevice), which after KickCAT's
//   state machine has run puts our plant's readings in the TxPDO objects, and
//   the frame loop of main(), the same as network_simulator's for one slave.
//
// Objects (the ESI's own; the run file maps them, configs/ethercat-exo.toml):
//   0x6071 target torque (RxPDO)   -> motor torque = value * exo_torque_scale_nm
//   0x6064 position actual         <- joint encoder counts
//   0x606C velocity actual         <- encoder counts per second (difference per frame)
//   0x6077 torque actual           <- applied motor torque / exo_torque_scale_nm
//   0x2051 secondary SSI position  <- SEA spring-deflection encoder counts
//   0x2052 BiSS-C slave 2 position <- cuff force f_y / exo_cuff_force_scale_n
// The drive's ESI has no object meant for a force sensor; a rig would read its
// cuff sensor on a slave of its own. The plant steps once per received frame
// (KickCAT steps a device per frame), one control period of the run per step.
//
// Usage: exo_plant_drive -i IFACE -s SLAVE.json -r RUN.toml

#include <algorithm>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <limits>
#include <string>

#include <argparse/argparse.hpp>
#include <nlohmann/json.hpp>

#include "kickcat/EmulatedNetwork.h"
#include "kickcat/Frame.h"
#include "kickcat/helpers.h"
#include "kickcat/simulation/SimulatedSlave.h"
#include "kickcat/simulation/devices/Ds402Motor.h"

#include "exo_plant_drive.h"

using namespace kickcat;
using json = nlohmann::json;

static volatile std::sig_atomic_t running = 1;
static void signalHandler(int) { running = 0; }

namespace
{
    namespace ds402 = CoE::CiA::DS402;

    // Saturating conversion to a PDO integer type.
    template<typename T>
    T saturate(double value)
    {
        if (not std::isfinite(value))
        {
            return 0;
        }
        double const lo = static_cast<double>(std::numeric_limits<T>::min());
        double const hi = static_cast<double>(std::numeric_limits<T>::max());
        return static_cast<T>(std::llround(std::clamp(value, lo, hi)));
    }

    class ExoPlantDevice : public sim::DeviceApp
    {
    public:
        struct Scales
        {
            double torque_nm;      // Nm per unit of 0x6071 / 0x6077
            double cuff_force_n;   // N per unit of the cuff object
        };

        ExoPlantDevice(slave::Slave& slave, ExoPlantDrive* plant, Scales scales)
            : slave_(&slave), cia402_(slave, inertStateMachine()), plant_(plant), scales_(scales)
        {
        }

        ~ExoPlantDevice() override { exo_plant_drive_close(plant_); }

        void step() override
        {
            // KickCAT's drive: controlword -> statusword, mode display.
            cia402_.step();

            State const s = slave_->state();
            if (s != State::SAFE_OP and s != State::OPERATIONAL)
            {
                bound_ = false;
                return;
            }
            if (not bound_)
            {
                bind();
                if (not bound_)
                {
                    return;
                }
            }

            bool const enabled = ((*status_word_ & ds402::status::value::ON_STATE) == ds402::status::value::ON_STATE)
                and (mode_ == nullptr or *mode_ == ds402::control::TORQUE_CYCLIC);
            double tau_nm = 0.0;
            if (enabled)
            {
                tau_nm = static_cast<double>(*target_torque_) * scales_.torque_nm;
            }
            ExoPlantReadings r{};
            int32_t const rc = exo_plant_drive_step(plant_, tau_nm, enabled ? 1 : 0, &r);
            if (rc != EXO_PLANT_DRIVE_OK)
            {
                if (not reported_)
                {
                    std::fprintf(stderr, "exo_plant_drive: plant step refused (%d); inputs held\n", rc);
                    reported_ = true;
                }
                return;
            }
            publish(r);
        }

    private:
        // KickCAT's drive is kept for its CiA 402 state machine only: its own
        // motor is made inert (no torque reaches it) and its outputs are
        // overwritten with our plant's every frame.
        static sim::Ds402Motor::Params inertStateMachine()
        {
            sim::Ds402Motor::Params p;
            p.torque_scale = 0.0;
            p.friction = 0.0;
            return p;
        }

        void bind()
        {
            slave_->bind(0x6041, status_word_);
            slave_->bind(0x6060, mode_);
            slave_->bind(0x6071, target_torque_);
            slave_->bind(0x6064, actual_position_);
            slave_->bind(0x606C, actual_velocity_);
            slave_->bind(0x6077, actual_torque_);
            slave_->bind(0x2051, sea_deflection_);
            slave_->bind(0x2052, cuff_force_);
            bound_ = status_word_ != nullptr and target_torque_ != nullptr and actual_position_ != nullptr;
            if (bound_)
            {
                ExoPlantReadings r{};
                if (exo_plant_drive_read(plant_, &r) == EXO_PLANT_DRIVE_OK)
                {
                    last_counts_ = r.encoder_counts;
                    publish(r);
                }
            }
        }

        void publish(ExoPlantReadings const& r)
        {
            *actual_position_ = saturate<int32_t>(static_cast<double>(r.encoder_counts));
            if (actual_velocity_ != nullptr and r.period_s > 0.0)
            {
                *actual_velocity_ = saturate<int32_t>(static_cast<double>(r.encoder_counts - last_counts_) / r.period_s);
            }
            last_counts_ = r.encoder_counts;
            if (actual_torque_ != nullptr)
            {
                *actual_torque_ = saturate<int16_t>(r.tau_motor_nm / scales_.torque_nm);
            }
            if (sea_deflection_ != nullptr)
            {
                *sea_deflection_ = saturate<int32_t>(static_cast<double>(r.sea_deflection_counts));
            }
            if (cuff_force_ != nullptr)
            {
                *cuff_force_ = saturate<int32_t>(r.cuff_wrench[1] / scales_.cuff_force_n);
            }
        }

        slave::Slave*   slave_;
        sim::Ds402Motor cia402_;
        ExoPlantDrive*  plant_;
        Scales          scales_;
        bool            bound_{false};
        bool            reported_{false};
        int64_t         last_counts_{0};

        uint16_t* status_word_{nullptr};
        int8_t*   mode_{nullptr};
        int16_t*  target_torque_{nullptr};
        int32_t*  actual_position_{nullptr};
        int32_t*  actual_velocity_{nullptr};
        int16_t*  actual_torque_{nullptr};
        int32_t*  sea_deflection_{nullptr};
        int32_t*  cuff_force_{nullptr};
    };

    double positiveScale(json const& config, char const* key)
    {
        double const v = config.value(key, 0.0);
        if (not std::isfinite(v) or v <= 0.0)
        {
            throw std::runtime_error(std::string("slave config: '") + key + "' must be a positive number");
        }
        return v;
    }
}

int main(int argc, char* argv[])
{
    std::signal(SIGINT, signalHandler);
    std::signal(SIGTERM, signalHandler);

    std::string interface;
    std::string slave_config;
    std::string run_file;
    argparse::ArgumentParser program("exo_plant_drive");
    program.add_argument("-i", "--interface").help("network interface").required().store_into(interface);
    program.add_argument("-s", "--slave").help("JSON slave configuration (ESI, scales)").required().store_into(slave_config);
    program.add_argument("-r", "--run").help("exo run file (plant model, subject, rate, instance)").required().store_into(run_file);
    try
    {
        program.parse_args(argc, argv);
    }
    catch (std::runtime_error const& err)
    {
        std::cerr << err.what() << std::endl << program;
        return 1;
    }

    sim::SimulatedSlave drive;
    ExoPlantDevice::Scales scales{};
    try
    {
        drive = sim::buildSlave(slave_config);
        std::ifstream f(slave_config);
        json const config = json::parse(f);
        scales.torque_nm = positiveScale(config, "exo_torque_scale_nm");
        scales.cuff_force_n = positiveScale(config, "exo_cuff_force_scale_n");
    }
    catch (std::exception const& e)
    {
        std::cerr << "exo_plant_drive: " << slave_config << ": " << e.what() << std::endl;
        return 1;
    }

    char err[512] = {0};
    ExoPlantDrive* plant = exo_plant_drive_open(run_file.c_str(), err, sizeof(err));
    if (plant == nullptr)
    {
        std::cerr << "exo_plant_drive: " << run_file << ": " << err << std::endl;
        return 1;
    }
    drive.device = std::make_unique<ExoPlantDevice>(*drive.slave, plant, scales);

    EmulatedNetwork network({drive.esc.get()});
    auto [socket, unused] = createSockets(interface, "");
    socket->setTimeout(100ms);
    drive.slave->start();
    std::printf("exo_plant_drive on %s: %s, run %s\n", interface.c_str(), slave_config.c_str(), run_file.c_str());
    std::fflush(stdout);

    while (running)
    {
        Frame frame;
        int32_t const n = socket->read(frame.data(), ETH_MAX_SIZE);
        if (n <= 0)
        {
            continue;
        }
        if (network.route(frame, false))
        {
            frame.data()[6] |= 0x02;  // a real ESC sets the U/L bit of the source MAC on the way back
            if (socket->write(frame.data(), n) < 0)
            {
                std::fprintf(stderr, "exo_plant_drive: cannot send a frame back\n");
                return 2;
            }
        }
        drive.slave->routine();
        if (drive.slave->state() == State::SAFE_OP
            and std::any_of(drive.output.begin(), drive.output.end(), [](uint8_t b) { return b != 0xFF; }))
        {
            drive.slave->validateOutputData();
        }
        drive.device->step();
    }
    return 0;
}
