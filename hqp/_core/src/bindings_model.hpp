// Python bindings of the native robot model (hqp._core._ext.RobotCore): the twin of
// hqp.model.RobotModel, for the kernels' tests and the native step's setup.
#pragma once

#include <nanobind/eigen/dense.h>
#include <nanobind/nanobind.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/tuple.h>
#include <nanobind/stl/vector.h>

#include <stdexcept>
#include <string>
#include <tuple>
#include <vector>

#include "model/robot.hpp"

namespace hqp {

namespace nb = nanobind;

inline void bind_model(nb::module_& m) {
  using Frames = std::vector<std::tuple<std::string, std::string, Eigen::Matrix4d>>;
  nb::class_<RobotCore>(m, "RobotCore")
      .def(
          "__init__",
          [](RobotCore* self, const std::string& urdf, const std::string& root,
             const Frames& frames) {
            std::vector<ExtraFrame> extra;
            for (const auto& [name, parent, T] : frames) {
              extra.push_back({name, parent,
                               pinocchio::SE3(Eigen::Matrix3d(T.topLeftCorner<3, 3>()),
                                              Eigen::Vector3d(T.topRightCorner<3, 1>()))});
            }
            new (self) RobotCore(urdf, root, extra);
          },
          nb::arg("urdf_path"), nb::arg("root_joint"), nb::arg("extra_frames"),
          "A URDF model, free flyer `root_joint` ('' for a fixed base), extra frames as "
          "(name, parent frame, 4x4 placement in the parent).")
      .def_prop_ro("nq", &RobotCore::nq)
      .def_prop_ro("nv", &RobotCore::nv)
      .def_prop_ro("mass", &RobotCore::mass)
      .def(
          "update",
          [](RobotCore& r, const Eigen::VectorXd& q, const Eigen::VectorXd& v) {
            if (q.size() != r.nq() || v.size() != r.nv()) {
              throw std::invalid_argument("state shapes q (" + std::to_string(q.size()) +
                                          "), v (" + std::to_string(v.size()) +
                                          "); expected (" + std::to_string(r.nq()) + "), (" +
                                          std::to_string(r.nv()) + ")");
            }
            nb::gil_scoped_release release;
            r.update(q, v);
          },
          nb::arg("q"), nb::arg("v"))
      .def("frame_id", &RobotCore::frame_id, nb::arg("name"))
      .def(
          "frame_jacobian",
          [](const RobotCore& r, int frame) {
            RobotCore::Matrix6Xd J(6, r.nv());
            r.frame_jacobian(frame, J);
            return Eigen::MatrixXd(J);
          },
          nb::arg("frame"))
      .def(
          "frame_velocity",
          [](const RobotCore& r, int frame) { return Eigen::VectorXd(r.frame_velocity(frame)); },
          nb::arg("frame"))
      .def(
          "frame_drift",
          [](const RobotCore& r, int frame) { return Eigen::VectorXd(r.frame_drift(frame)); },
          nb::arg("frame"))
      .def(
          "frame_placement",
          [](const RobotCore& r, int frame) {
            return Eigen::Matrix4d(r.frame_placement(frame).toHomogeneousMatrix());
          },
          nb::arg("frame"))
      .def_prop_ro("M", [](const RobotCore& r) { return Eigen::MatrixXd(r.M()); })
      .def_prop_ro("h", [](const RobotCore& r) { return Eigen::VectorXd(r.h()); })
      .def_prop_ro("gravity", [](const RobotCore& r) { return Eigen::VectorXd(r.g()); })
      .def_prop_ro("com", [](const RobotCore& r) { return Eigen::Vector3d(r.com()); })
      .def_prop_ro("com_velocity",
                   [](const RobotCore& r) { return Eigen::Vector3d(r.com_velocity()); })
      .def_prop_ro("com_drift", [](const RobotCore& r) { return Eigen::Vector3d(r.com_drift()); })
      .def_prop_ro("com_jacobian",
                   [](const RobotCore& r) { return Eigen::MatrixXd(r.com_jacobian()); })
      .def_prop_ro("centroidal_matrix",
                   [](const RobotCore& r) { return Eigen::MatrixXd(r.centroidal_matrix()); })
      .def_prop_ro("centroidal_drift",
                   [](const RobotCore& r) { return Eigen::VectorXd(r.centroidal_drift()); });
}

}  // namespace hqp
