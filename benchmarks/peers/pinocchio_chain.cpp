// Peer of the `scale` suite: classic RK4 (fixed step) on Pinocchio's ABA for lagcodegen's planar
// n-link pendulum chain (catalog.pendulum_chain(n)): point masses m_i = 1 on massless rods
// l_i = 1, hinged at the origin, gravity 9.81.
//
// The chain is built programmatically: joint i is a JointModelRY placed at (0, 0, -l_{i-1}) in
// its parent's frame (at the origin for i = 1); body i is a point mass at (0, 0, -l_i) in joint
// i's frame, with rotational inertia `inertia` * I3 about it (1e-12 by default, as the MuJoCo
// model, which needs > 0; 0 is accepted too). Coordinates are Pinocchio's relative joint angles
// theta_i (absolute angle q_i = theta_1 + ... + theta_i; RY turns +z towards +x, MuJoCo's hinge
// about -y turns -z towards +x: both sign conventions give the same equations in the angles,
// the chain being symmetric under x -> -x).
//
// Usage:  pinocchio_chain N CHECK_STEPS TARGET_SECONDS REPEATS [INERTIA [CONVENTION]] < state
//   state: 2N numbers, relative joint angles then relative joint speeds; CONVENTION: local
//   (aba's default, Convention::LOCAL) or world (Convention::WORLD, Pinocchio 3's other ABA).
// Prints one line of JSON: the state after CHECK_STEPS steps of h = 1e-3 from the given state,
// then the timing: the step count is grown until one run from the given state lasts
// TARGET_SECONDS / 4 (the warm-up), sized for TARGET_SECONDS, run REPEATS times; best wall
// (CLOCK_MONOTONIC) and best CPU (CLOCK_PROCESS_CPUTIME_ID) nanoseconds per step.
//
// Built by bench_scale.build_pinocchio_chain with g++ -O3 -march=native -DNDEBUG, either header
// only (every Pinocchio template instantiated here, with these flags) or with
// -DPINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION against the wheel's libpinocchio_default (aba then
// comes precompiled from the library: the call below passes Eigen::Ref<const VectorXd>
// arguments, the types of its explicit instantiations).
#include <pinocchio/multibody.hpp>  // Pinocchio 4: Model, Data and the joints in one header
#include <pinocchio/algorithm/aba.hpp>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <iostream>
#include <string>

namespace {

using Vec = Eigen::VectorXd;
using ConstRef = Eigen::Ref<const Vec>;

const double H = 1e-3;

pinocchio::Model chain(int n, double inertia)
{
    pinocchio::Model model;
    model.gravity.linear(Eigen::Vector3d(0.0, 0.0, -9.81));
    pinocchio::JointIndex parent = 0;
    const double mass = 1.0, length = 1.0;
    for (int i = 0; i < n; ++i) {
        const Eigen::Vector3d offset(0.0, 0.0, i == 0 ? 0.0 : -length);
        const pinocchio::SE3 placement(Eigen::Matrix3d::Identity(), offset);
        parent = model.addJoint(parent, pinocchio::JointModelRY(), placement, "theta" + std::to_string(i + 1));
        const pinocchio::Inertia body(mass, Eigen::Vector3d(0.0, 0.0, -length),
                                      pinocchio::Symmetric3(inertia, 0.0, inertia, 0.0, 0.0, inertia));
        model.appendBodyToJoint(parent, body, pinocchio::SE3::Identity());
    }
    return model;
}

struct Rk4 {
    const pinocchio::Model &model;
    pinocchio::Data data;
    Vec tau, q2, v2, k1q, k1v, k2q, k2v, k3q, k3v, k4q, k4v;

    Rk4(const pinocchio::Model &m)
        : model(m), data(m), tau(Vec::Zero(m.nv)), q2(m.nq), v2(m.nv), k1q(m.nv), k1v(m.nv), k2q(m.nv),
          k2v(m.nv), k3q(m.nv), k3v(m.nv), k4q(m.nv), k4v(m.nv) {}

    pinocchio::Convention convention = pinocchio::Convention::LOCAL;

    void accel(const Vec &q, const Vec &v, Vec &out)
    {
        out = pinocchio::aba(model, data, ConstRef(q), ConstRef(v), ConstRef(tau), convention);
    }

    // n_steps classic RK4 steps in place; revolute (bounded) joints: q lives in R^n, so
    // q + h v is the configuration integration.
    void run(Vec &q, Vec &v, long n_steps)
    {
        for (long k = 0; k < n_steps; ++k) {
            k1q = v;
            accel(q, v, k1v);
            q2.noalias() = q + (0.5 * H) * k1q;
            v2.noalias() = v + (0.5 * H) * k1v;
            k2q = v2;
            accel(q2, v2, k2v);
            q2.noalias() = q + (0.5 * H) * k2q;
            v2.noalias() = v + (0.5 * H) * k2v;
            k3q = v2;
            accel(q2, v2, k3v);
            q2.noalias() = q + H * k3q;
            v2.noalias() = v + H * k3v;
            k4q = v2;
            accel(q2, v2, k4v);
            q.noalias() += (H / 6.0) * (k1q + 2.0 * k2q + 2.0 * k3q + k4q);
            v.noalias() += (H / 6.0) * (k1v + 2.0 * k2v + 2.0 * k3v + k4v);
        }
    }
};

double seconds(clockid_t clock)
{
    timespec ts;
    clock_gettime(clock, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

}  // namespace

int main(int argc, char **argv)
{
    if (argc < 5) {
        std::fprintf(stderr, "usage: %s N CHECK_STEPS TARGET_SECONDS REPEATS [INERTIA] < state\n", argv[0]);
        return 2;
    }
    const int n = std::atoi(argv[1]);
    const long check_steps = std::atol(argv[2]);
    const double target = std::atof(argv[3]);
    const int repeats = std::atoi(argv[4]);
    const double inertia = argc > 5 ? std::atof(argv[5]) : 1e-12;
    const std::string convention = argc > 6 ? argv[6] : "local";
    if (n < 1 || check_steps < 0 || !(target > 0.0) || repeats < 1 || !(inertia >= 0.0) ||
        (convention != "local" && convention != "world")) {
        std::fprintf(stderr, "bad arguments\n");
        return 2;
    }
    Vec q0(n), v0(n);
    for (int i = 0; i < 2 * n; ++i) {
        double value;
        if (!(std::cin >> value)) {
            std::fprintf(stderr, "expected %d state values on stdin\n", 2 * n);
            return 2;
        }
        (i < n ? q0[i] : v0[i - n]) = value;
    }
    const pinocchio::Model model = chain(n, inertia);
    Rk4 rk4(model);
    rk4.convention = convention == "world" ? pinocchio::Convention::WORLD : pinocchio::Convention::LOCAL;

    Vec q = q0, v = v0;
    rk4.run(q, v, check_steps);
    std::printf("{\"n\": %d, \"nq\": %d, \"nv\": %d, \"inertia\": %.17g, \"convention\": \"%s\", "
                "\"check_steps\": %ld, \"final\": [",
                n, int(model.nq), int(model.nv), inertia, convention.c_str(), check_steps);
    for (int i = 0; i < 2 * n; ++i) std::printf("%s%.17g", i ? ", " : "", i < n ? q[i] : v[i - n]);
    std::printf("]");

    long steps = 1;
    double wall = 0.0;
    for (;;) {  // warm-up and calibration
        q = q0, v = v0;
        const double start = seconds(CLOCK_MONOTONIC);
        rk4.run(q, v, steps);
        wall = seconds(CLOCK_MONOTONIC) - start;
        if (wall >= target / 4 || steps >= (1L << 40)) break;
        steps *= 4;
    }
    steps = std::max(1L, long(std::ceil(steps * target / std::max(wall, 1e-9))));
    double best_wall = 1e300, best_cpu = 1e300, checksum = 0.0;
    bool finite = true;
    for (int r = 0; r < repeats; ++r) {
        q = q0, v = v0;
        const double w0 = seconds(CLOCK_MONOTONIC), c0 = seconds(CLOCK_PROCESS_CPUTIME_ID);
        rk4.run(q, v, steps);
        const double c1 = seconds(CLOCK_PROCESS_CPUTIME_ID), w1 = seconds(CLOCK_MONOTONIC);
        best_wall = std::min(best_wall, w1 - w0);
        best_cpu = std::min(best_cpu, c1 - c0);
        finite = finite && q.allFinite() && v.allFinite();
        checksum += q.sum() + v.sum();
    }
    std::printf(", \"steps\": %ld, \"repeats\": %d, \"wall_ns_per_step\": %.6g, \"cpu_ns_per_step\": %.6g, "
                "\"finite\": %s, \"checksum\": %.17g}\n",
                steps, repeats, 1e9 * best_wall / steps, 1e9 * best_cpu / steps, finite ? "true" : "false",
                checksum);
    return 0;
}
