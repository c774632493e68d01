// Python bindings of the native task kernels, for their tests against the Python tasks
// (the oracle) and, from the native step on, for reading a kernel's rows.
#pragma once

#include <nanobind/eigen/dense.h>
#include <nanobind/nanobind.h>
#include <nanobind/stl/string.h>

#include <stdexcept>
#include <string>

#include "tasks/reference.hpp"
#include "tasks/vector_tracking.hpp"

namespace hqp {

namespace nb = nanobind;

inline PDGains make_gains(double kp, double kv, double max_velocity, double max_acceleration) {
  PDGains g;
  g.kp = kp;
  g.kv = kv;
  g.max_velocity = max_velocity;
  g.max_acceleration = max_acceleration;
  return g;
}

inline void bind_tasks(nb::module_& m) {
  m.def(
      "pd_feedback",
      [](const Eigen::VectorXd& e, const Eigen::VectorXd& rate, double kp, double kv,
         double max_velocity, double max_acceleration) {
        if (e.size() != rate.size()) throw std::invalid_argument("error and rate sizes differ");
        Eigen::VectorXd out(e.size());
        pd_feedback(make_gains(kp, kv, max_velocity, max_acceleration), e, rate, out);
        return out;
      },
      nb::arg("error"), nb::arg("rate"), nb::arg("kp"), nb::arg("kv"), nb::arg("max_velocity"),
      nb::arg("max_acceleration"), "a_fb of seed 003 eq. 27-28 (hqp.tasks.reference.PDReference).");
  nb::class_<VectorTracking>(m, "VectorTracking")
      .def(
          "__init__",
          [](VectorTracking* self, const std::string& kind, int frame,
             const Eigen::VectorXi& select, const Eigen::VectorXi& v_index,
             const Eigen::VectorXd& scale, double kp, double kv, double max_velocity,
             double max_acceleration) {
            VectorTracking::Kind k;
            if (kind == "frame_position")
              k = VectorTracking::Kind::kFramePosition;
            else if (kind == "com")
              k = VectorTracking::Kind::kCenterOfMass;
            else if (kind == "joints")
              k = VectorTracking::Kind::kJoints;
            else
              throw std::invalid_argument("unknown tracking kind '" + kind + "'");
            new (self) VectorTracking(k, frame, select, v_index, scale,
                                      make_gains(kp, kv, max_velocity, max_acceleration));
          },
          nb::arg("kind"), nb::arg("frame"), nb::arg("select"), nb::arg("v_index"),
          nb::arg("scale"), nb::arg("kp"), nb::arg("kv"), nb::arg("max_velocity"),
          nb::arg("max_acceleration"))
      .def("rows", &VectorTracking::rows)
      .def("set_goal", &VectorTracking::set_goal, nb::arg("position"), nb::arg("velocity"),
           nb::arg("acceleration"))
      .def(
          "write",
          [](VectorTracking& t, const RobotCore& robot, Eigen::Index n) {
            if (n < robot.nv()) throw std::invalid_argument("n below the robot's nv");
            Eigen::MatrixXd A(t.rows(), n);
            Eigen::VectorXd b(t.rows());
            t.write(robot, A, b);
            return nb::make_tuple(A, b);
          },
          nb::arg("robot"), nb::arg("n"))
      .def_prop_ro("error", [](const VectorTracking& t) { return Eigen::VectorXd(t.error()); })
      .def_prop_ro("reference_acceleration", [](const VectorTracking& t) {
        return Eigen::VectorXd(t.reference_acceleration());
      });
}

}  // namespace hqp
