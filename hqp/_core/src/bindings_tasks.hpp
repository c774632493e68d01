// Python bindings of the native task kernels, for their tests against the Python tasks
// (the oracle) and, from the native step on, for reading a kernel's rows.
#pragma once

#include <nanobind/eigen/dense.h>
#include <nanobind/nanobind.h>
#include <nanobind/stl/string.h>

#include <stdexcept>
#include <optional>
#include <string>
#include <tuple>
#include <vector>

#include <nanobind/stl/optional.h>
#include <nanobind/stl/tuple.h>
#include <nanobind/stl/vector.h>

#include "tasks/joint_limits.hpp"
#include "tasks/orientation.hpp"
#include "tasks/physics.hpp"
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

inline LayoutC make_layout(Eigen::Index nv, const std::vector<std::tuple<int, int, Eigen::Index>>& slots) {
  LayoutC layout;
  layout.nv = nv;
  for (const auto& [frame, size, start] : slots) {
    if (size != 3 && size != 6) throw std::invalid_argument("contact slot size must be 3 or 6");
    layout.slots.push_back({frame, size, start});
  }
  return layout;
}

inline void bind_tasks(nb::module_& m) {
  m.def(
      "joint_limit_bounds",
      [](const Eigen::VectorXd& q, const Eigen::VectorXd& v, const Eigen::VectorXd& q_lower,
         const Eigen::VectorXd& q_upper, const Eigen::VectorXd& v_max, const Eigen::VectorXd& A,
         const Eigen::VectorXd& B, double dt, double reserve, double velocity_time,
         double inactive_beyond, bool acceleration_bounds, double approach_time) {
        const Eigen::Index k = q.size();
        for (const Eigen::VectorXd* a : {&v, &q_lower, &q_upper, &v_max, &A, &B}) {
          if (a->size() != k) throw std::invalid_argument("joint_limit_bounds: sizes differ");
        }
        JointLimitParams p{q_lower, q_upper, v_max, reserve, velocity_time, inactive_beyond,
                           acceleration_bounds, approach_time};
        Eigen::VectorXd lb(k), ub(k);
        joint_limit_bounds(p, q, v, A, B, dt, lb, ub);
        return nb::make_tuple(lb, ub);
      },
      nb::arg("q"), nb::arg("v"), nb::arg("q_lower"), nb::arg("q_upper"), nb::arg("v_max"),
      nb::arg("A"), nb::arg("B"), nb::arg("dt"), nb::arg("reserve"), nb::arg("velocity_time"),
      nb::arg("inactive_beyond"), nb::arg("acceleration_bounds"), nb::arg("approach_time") = 0.0,
      "Viable joint-limit acceleration bounds (lb, ub) (hqp.tasks.joint_limits.JointLimits).");
  m.def(
      "contact_dynamics",
      [](const RobotCore& robot, const std::vector<std::tuple<int, int, Eigen::Index>>& slots) {
        const LayoutC layout = make_layout(robot.nv(), slots);
        Eigen::MatrixXd G = Eigen::MatrixXd::Zero(robot.nv(), layout.n());
        RobotCore::Matrix6Xd J6(6, robot.nv());
        contact_dynamics(robot, layout, G, J6);
        return G;
      },
      nb::arg("robot"), nb::arg("slots"),
      "[M | -J_1^T ... -J_k^T] (nv, n) for contact slots (frame, size, start).");
  m.def("contact_local_limits", &contact_local_limits, nb::arg("size"), nb::arg("mu"),
        nb::arg("half_length"), nb::arg("half_width"));
  nb::class_<ContactKernel>(m, "ContactKernel")
      .def(
          "__init__",
          [](ContactKernel* self, int frame, int size, Eigen::Index start, double mu,
             double half_length, double half_width, double f_min, double f_max, double kp,
             double kd) {
            if (size != 3 && size != 6) throw std::invalid_argument("contact size must be 3 or 6");
            new (self) ContactKernel({frame, size, start}, mu, half_length, half_width, f_min,
                                     f_max, kp, kd);
          },
          nb::arg("frame"), nb::arg("size"), nb::arg("start"), nb::arg("mu"),
          nb::arg("half_length"), nb::arg("half_width"), nb::arg("f_min"), nb::arg("f_max"),
          nb::arg("kp"), nb::arg("kd"))
      .def("deactivate", &ContactKernel::deactivate)
      .def(
          "activate",
          [](ContactKernel& k, std::optional<Eigen::Matrix4d> T) {
            if (!T) {
              k.activate();
              return;
            }
            k.activate(pinocchio::SE3(Eigen::Matrix3d(T->topLeftCorner<3, 3>()),
                                      Eigen::Vector3d(T->topRightCorner<3, 1>())));
          },
          nb::arg("reference").none() = nb::none())
      .def(
          "write",
          [](ContactKernel& k, const RobotCore& robot, Eigen::Index n) {
            Eigen::MatrixXd A(k.rows(), n);
            Eigen::VectorXd b(k.rows());
            k.write(robot, A, b);
            return nb::make_tuple(A, b);
          },
          nb::arg("robot"), nb::arg("n"))
      .def(
          "write_limits",
          [](const ContactKernel& k, const RobotCore& robot, Eigen::Index n) {
            Eigen::MatrixXd C(k.limit_rows(), n);
            Eigen::VectorXd lo(k.limit_rows()), up(k.limit_rows());
            k.write_limits(robot, C, lo, up);
            return nb::make_tuple(C, lo, up);
          },
          nb::arg("robot"), nb::arg("n"));
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
  nb::class_<OrientationTracking>(m, "OrientationTracking")
      .def(
          "__init__",
          [](OrientationTracking* self, int frame, double kp, double kv, double max_velocity,
             double max_acceleration) {
            new (self) OrientationTracking(frame, make_gains(kp, kv, max_velocity, max_acceleration));
          },
          nb::arg("frame"), nb::arg("kp"), nb::arg("kv"), nb::arg("max_velocity"),
          nb::arg("max_acceleration"))
      .def("set_goal", &OrientationTracking::set_goal, nb::arg("rotation"), nb::arg("velocity"),
           nb::arg("acceleration"))
      .def(
          "write",
          [](OrientationTracking& t, const RobotCore& robot, Eigen::Index n) {
            if (n < robot.nv()) throw std::invalid_argument("n below the robot's nv");
            Eigen::MatrixXd A(3, n);
            Eigen::VectorXd b(3);
            t.write(robot, A, b);
            return nb::make_tuple(A, b);
          },
          nb::arg("robot"), nb::arg("n"))
      .def_prop_ro("error", [](const OrientationTracking& t) { return Eigen::Vector3d(t.error()); })
      .def_prop_ro("reference_acceleration", [](const OrientationTracking& t) {
        return Eigen::Vector3d(t.reference_acceleration());
      });
  m.def(
      "jlog3_rate_times",
      [](const Eigen::Vector3d& e, const Eigen::Vector3d& de, const Eigen::Vector3d& xi) {
        return Eigen::Vector3d(jlog3_rate_times(e, de, xi));
      },
      nb::arg("e"), nb::arg("de"), nb::arg("xi"));
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
            else if (kind == "centroidal")
              k = VectorTracking::Kind::kCentroidal;
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
