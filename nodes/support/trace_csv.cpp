#include "trace_csv.hpp"

#include <sstream>

#include "pmlsm/util/atomic_file.hpp"

namespace pmlsm {

void write_trace_csv(const std::string& path, const std::vector<TickRecord>& trace) {
  std::ostringstream out;
  out.precision(9);
  out << "tick,time_s,command_mps,v_ref_mps,encoder_position_m,motor_velocity_measured_mps,"
         "motor_position_m,motor_velocity_mps,load_position_m,load_velocity_mps,load_accel_mps2,"
         "spring_force_n,est_motor_velocity_mps,est_load_velocity_mps,est_spring_force_n,"
         "est_load_accel_mps2,force_command_n,compensation_force_n,thrust_n,ripple_n,friction_n,i_q_a,u_q_v,"
         "load_position_measured_m,load_accel_measured_mps2,load_sensor_use\n";
  for (const TickRecord& r : trace) {
    out << r.tick << ',' << r.time_s << ',' << r.command_mps << ',' << r.v_ref_mps << ',' << r.encoder_position_m << ','
        << r.motor_velocity_measured_mps << ',' << r.motor_position_m << ',' << r.motor_velocity_mps << ','
        << r.load_position_m << ',' << r.load_velocity_mps << ',' << r.load_accel_mps2 << ',' << r.spring_force_n << ','
        << r.est_motor_velocity_mps << ',' << r.est_load_velocity_mps << ',' << r.est_spring_force_n << ','
        << r.est_load_accel_mps2 << ',' << r.force_command_n << ',' << r.compensation_force_n << ',' << r.thrust_n
        << ',' << r.ripple_n << ',' << r.friction_n << ',' << r.i_q_a << ',' << r.u_q_v << ','
        << r.load_position_measured_m << ',' << r.load_accel_measured_mps2 << ',' << static_cast<int>(r.load_sensor_use)
        << '\n';
  }
  write_file_atomically(path, out.str());
}

}  // namespace pmlsm
