// The C ABI of exo-plant-drive (src/lib.rs): our plant (SEA, arm, simulated
// human of exo-plant-sim), one control period per call. Units: Nm, N, s, counts.
#ifndef EXO_PLANT_DRIVE_H
#define EXO_PLANT_DRIVE_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define EXO_PLANT_DRIVE_OK 0
#define EXO_PLANT_DRIVE_NULL (-1)
#define EXO_PLANT_DRIVE_NOT_FINITE (-2)
#define EXO_PLANT_DRIVE_IPC (-3)
#define EXO_PLANT_DRIVE_PANIC (-4)

typedef struct ExoPlantDrive ExoPlantDrive;

typedef struct
{
    int64_t encoder_counts;         // joint encoder counts
    int64_t sea_deflection_counts;  // SEA spring-deflection encoder counts
    double  cuff_wrench[6];         // f_x, f_y, f_z (N), t_x, t_y, t_z (Nm)
    double  tau_motor_nm;           // motor torque applied now (Nm)
    double  t_s;                    // simulated time (s)
    double  period_s;               // one step: the run's control period (s)
} ExoPlantReadings;

ExoPlantDrive* exo_plant_drive_open(char const* run_file, char* err, size_t err_len);
int32_t exo_plant_drive_read(ExoPlantDrive* plant, ExoPlantReadings* out);
int32_t exo_plant_drive_step(ExoPlantDrive* plant, double tau_motor_nm, uint8_t enabled,
                             ExoPlantReadings* out);
void exo_plant_drive_close(ExoPlantDrive* plant);

#ifdef __cplusplus
}
#endif

#endif
