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

#include "tasks/collision.hpp"
#include "tasks/cop.hpp"
#include "tasks/gaze.hpp"
#include "tasks/internal_forces.hpp"
#include "tasks/joint_limits.hpp"
#include "tasks/orientation.hpp"
#include "tasks/physics.hpp"
#include "tasks/pose.hpp"
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

inline CapsuleC make_capsule(int frame, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                             double radius) {
  if (frame < 0) throw std::invalid_argument("capsule: no such frame");
  return CapsuleC{frame, a, b, radius};
}

inline void check_columns(const RobotCore& robot, Eigen::Index n) {
  if (n < robot.nv()) throw std::invalid_argument("n below the robot's nv");
}

inline void bind_kernels(nb::module_& m) {
  nb::class_<GazeKernel>(m, "GazeKernel")
      .def(
          "__init__",
          [](GazeKernel* self, int frame, const Eigen::Vector3d& axis,
             const Eigen::Matrix<double, 2, 3>& plane, double kp, double kv, double max_velocity,
             double max_acceleration) {
            new (self) GazeKernel(frame, axis, plane, make_gains(kp, kv, max_velocity,
                                                                  max_acceleration));
          },
          nb::arg("frame"), nb::arg("axis"), nb::arg("plane"), nb::arg("kp"), nb::arg("kv"),
          nb::arg("max_velocity"), nb::arg("max_acceleration"))
      .def("set_goal", &GazeKernel::set_goal, nb::arg("position"), nb::arg("velocity"),
           nb::arg("acceleration"))
      .def(
          "write",
          [](GazeKernel& k, const RobotCore& robot, Eigen::Index n) {
            check_columns(robot, n);
            Eigen::MatrixXd A(2, n);
            Eigen::VectorXd b(2);
            if (const char* why = k.write(robot, A, b)) throw std::invalid_argument(why);
            return nb::make_tuple(A, b);
          },
          nb::arg("robot"), nb::arg("n"))
      .def_prop_ro("error", [](const GazeKernel& k) { return Eigen::VectorXd(k.error()); })
      .def_prop_ro("rate", [](const GazeKernel& k) { return Eigen::VectorXd(k.rate()); })
      .def_prop_ro("drift", [](const GazeKernel& k) { return Eigen::VectorXd(k.drift()); })
      .def_prop_ro("reference_acceleration", [](const GazeKernel& k) {
        return Eigen::VectorXd(k.reference_acceleration());
      });
  nb::class_<InternalForcesKernel>(m, "InternalForcesKernel")
      .def(
          "__init__",
          [](InternalForcesKernel* self, int frame1, int size, Eigen::Index start1, int frame2,
             Eigen::Index start2, const Eigen::VectorXi& components) {
            if (size != 3 && size != 6) throw std::invalid_argument("contact size must be 3 or 6");
            new (self) InternalForcesKernel({frame1, size, start1}, {frame2, size, start2},
                                            components);
          },
          nb::arg("frame1"), nb::arg("size"), nb::arg("start1"), nb::arg("frame2"),
          nb::arg("start2"), nb::arg("components"))
      .def("rows", &InternalForcesKernel::rows)
      .def("set_goal", &InternalForcesKernel::set_goal, nb::arg("goal"))
      .def(
          "write",
          [](const InternalForcesKernel& k, const RobotCore& robot, Eigen::Index n) {
            check_columns(robot, n);
            Eigen::MatrixXd A(k.rows(), n);
            Eigen::VectorXd b(k.rows());
            if (const char* why = k.write(robot, A, b)) throw std::invalid_argument(why);
            return nb::make_tuple(A, b);
          },
          nb::arg("robot"), nb::arg("n"));
  nb::class_<DistanceKernel>(m, "DistanceKernel")
      .def(
          "__init__",
          [](DistanceKernel* self, double d_safe, double d_influence, double xi, double kv) {
            new (self) DistanceKernel(DistanceParams{d_safe, d_influence, xi, kv});
          },
          nb::arg("d_safe"), nb::arg("d_influence"), nb::arg("xi"), nb::arg("kv"),
          "kv <= 0: 1 / dt.")
      .def(
          "add_pair",
          [](DistanceKernel& k, int frame1, const Eigen::Vector3d& a1, const Eigen::Vector3d& b1,
             double r1, int frame2, const Eigen::Vector3d& a2, const Eigen::Vector3d& b2,
             double r2) {
            return k.add_pair(make_capsule(frame1, a1, b1, r1), make_capsule(frame2, a2, b2, r2));
          },
          nb::arg("frame1"), nb::arg("a1"), nb::arg("b1"), nb::arg("radius1"), nb::arg("frame2"),
          nb::arg("a2"), nb::arg("b2"), nb::arg("radius2"))
      .def(
          "add_obstacle_pair",
          [](DistanceKernel& k, int frame, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
             double radius, int obstacle) {
            return k.add_obstacle_pair(make_capsule(frame, a, b, radius), obstacle);
          },
          nb::arg("frame"), nb::arg("a"), nb::arg("b"), nb::arg("radius"), nb::arg("obstacle"))
      .def("set_obstacle", &DistanceKernel::set_obstacle, nb::arg("obstacle"), nb::arg("a"),
           nb::arg("b"), nb::arg("velocity"), nb::arg("radius"))
      .def("rows", &DistanceKernel::rows)
      .def(
          "write",
          [](DistanceKernel& k, const RobotCore& robot, double dt, Eigen::Index n) {
            check_columns(robot, n);
            if (!(dt > 0.0)) throw std::invalid_argument("dt must be > 0");
            Eigen::MatrixXd C(k.rows(), n);
            Eigen::VectorXd lo(k.rows()), up(k.rows());
            k.write(robot, dt, C, lo, up);
            return nb::make_tuple(C, lo, up);
          },
          nb::arg("robot"), nb::arg("dt"), nb::arg("n"))
      .def_prop_ro("margins", [](const DistanceKernel& k) { return Eigen::VectorXd(k.margins()); })
      .def_prop_ro("distance", [](const DistanceKernel& k) { return Eigen::VectorXd(k.distance()); })
      .def_prop_ro("rate", [](const DistanceKernel& k) { return Eigen::VectorXd(k.rate()); })
      .def_prop_ro("drift", [](const DistanceKernel& k) { return Eigen::VectorXd(k.drift()); });
  nb::class_<PoseKernel>(m, "PoseKernel")
      .def(
          "__init__",
          [](PoseKernel* self, int frame, const Eigen::VectorXi& linear,
             const Eigen::VectorXi& angular, bool world_rotation, double kp, double kv,
             double max_velocity, double max_acceleration, double max_angular_velocity,
             double max_angular_acceleration, Eigen::Index force_start,
             const Eigen::VectorXi& force_index) {
            new (self) PoseKernel(frame, linear, angular, world_rotation,
                                  make_gains(kp, kv, max_velocity, max_acceleration),
                                  make_gains(kp, kv, max_angular_velocity,
                                             max_angular_acceleration),
                                  force_start, force_index);
          },
          nb::arg("frame"), nb::arg("linear"), nb::arg("angular"), nb::arg("world_rotation"),
          nb::arg("kp"), nb::arg("kv"), nb::arg("max_velocity"), nb::arg("max_acceleration"),
          nb::arg("max_angular_velocity"), nb::arg("max_angular_acceleration"),
          nb::arg("force_start"), nb::arg("force_index"))
      .def("rows", &PoseKernel::rows)
      .def("set_goal", &PoseKernel::set_goal, nb::arg("placement"), nb::arg("velocity"),
           nb::arg("acceleration"))
      .def("set_force", &PoseKernel::set_force, nb::arg("force"))
      .def(
          "write",
          [](PoseKernel& k, const RobotCore& robot, Eigen::Index n) {
            check_columns(robot, n);
            Eigen::MatrixXd A(k.rows(), n);
            Eigen::VectorXd b(k.rows());
            k.write(robot, A, b);
            return nb::make_tuple(A, b);
          },
          nb::arg("robot"), nb::arg("n"))
      .def_prop_ro("error", [](const PoseKernel& k) { return Eigen::VectorXd(k.error()); })
      .def_prop_ro("rate", [](const PoseKernel& k) { return Eigen::VectorXd(k.rate()); })
      .def_prop_ro("drift", [](const PoseKernel& k) { return Eigen::VectorXd(k.drift()); })
      .def_prop_ro("reference_acceleration", [](const PoseKernel& k) {
        return Eigen::VectorXd(k.reference_acceleration());
      });
}

inline void bind_tasks(nb::module_& m) {
  bind_kernels(m);
  nb::class_<CoPKernel>(m, "CoPKernel")
      .def(
          "__init__",
          [](CoPKernel* self, const std::vector<std::tuple<int, int, Eigen::Index>>& slots,
             double height, double scale) {
            std::vector<ContactSlotC> s;
            for (const auto& [frame, size, start] : slots) {
              if (size != 3 && size != 6) throw std::invalid_argument("contact size must be 3 or 6");
              s.push_back({frame, size, start});
            }
            new (self) CoPKernel(s, height, scale);
          },
          nb::arg("slots"), nb::arg("height"), nb::arg("scale"),
          "slots: (frame, size, start); height NaN: the slots' mean height at each state.")
      .def("set_goal", &CoPKernel::set_goal, nb::arg("goal"))
      .def(
          "write",
          [](const CoPKernel& k, const RobotCore& robot, Eigen::Index n) {
            check_columns(robot, n);
            Eigen::MatrixXd A(2, n);
            Eigen::VectorXd b(2);
            k.write(robot, A, b);
            return nb::make_tuple(A, b);
          },
          nb::arg("robot"), nb::arg("n"));
  m.def(
      "joint_limit_bounds",
      [](const Eigen::VectorXd& q, const Eigen::VectorXd& v, const Eigen::VectorXd& q_lower,
         const Eigen::VectorXd& q_upper, const Eigen::VectorXd& v_max, const Eigen::VectorXd& A,
         const Eigen::VectorXd& B, double dt, double reserve, double velocity_time,
         double inactive_beyond, bool acceleration_bounds, double approach_time,
         const Eigen::VectorXd& recovery) {
        const Eigen::Index k = q.size();
        for (const Eigen::VectorXd* a : {&v, &q_lower, &q_upper, &v_max, &A, &B}) {
          if (a->size() != k) throw std::invalid_argument("joint_limit_bounds: sizes differ");
        }
        if (recovery.size() != 0 && recovery.size() != k)
          throw std::invalid_argument("joint_limit_bounds: sizes differ");
        JointLimitParams p{q_lower, q_upper, v_max, reserve, velocity_time, inactive_beyond,
                           acceleration_bounds, approach_time, recovery};
        Eigen::VectorXd lb(k), ub(k);
        joint_limit_bounds(p, q, v, A, B, dt, lb, ub);
        return nb::make_tuple(lb, ub);
      },
      nb::arg("q"), nb::arg("v"), nb::arg("q_lower"), nb::arg("q_upper"), nb::arg("v_max"),
      nb::arg("A"), nb::arg("B"), nb::arg("dt"), nb::arg("reserve"), nb::arg("velocity_time"),
      nb::arg("inactive_beyond"), nb::arg("acceleration_bounds"), nb::arg("approach_time") = 0.0,
      nb::arg("recovery") = Eigen::VectorXd(),
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
      .def("set_max_normal_force", &ContactKernel::set_max_normal_force, nb::arg("f_max"))
      .def_prop_ro("max_normal_force", &ContactKernel::max_normal_force)
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
      .def_prop_ro("rate", [](const VectorTracking& t) { return Eigen::VectorXd(t.rate()); })
      .def_prop_ro("reference_acceleration", [](const VectorTracking& t) {
        return Eigen::VectorXd(t.reference_acceleration());
      });
}

}  // namespace hqp
