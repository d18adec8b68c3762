// Reference throughput benchmark in Enki, mirroring tavc's `two_circuits` bench scenario.
//
// Units: Enki's convention, lengths in cm, speeds in cm/s, angles in rad, time in s.
// The arena is 1200 x 800 cm (12 m x 8 m) with Enki's own square walls.
//
// Six Pioneer-sized robots (discs of 22 cm radius, mass 15, differential drive, 25 cm/s top
// speed) run two crossing circuits between targets on the long walls: circuit 0 from the
// source at (400, 800) to the sink at (800, 0), circuit 1 from (800, 800) to (400, 0).
// Robot i serves circuit i % 2, alternating source -> sink -> source ... and counting an
// arrival each time its centre comes within 50 cm of the current target.
//
// Each robot carries two Enki::CircularCam:
//   - a range scan: 16 pixels over 180 degrees (-90 .. +90 deg, 12 deg apart), 8 m range; its
//     depth buffer (squared distances) is read as laser ranges;
//   - a colour camera: 60 pixels over 80 degrees, 6 m range; the controller finds runs of
//     robot-coloured (red) pixels and takes the bearing of the nearest one.
// The controller runs every control tick (0.1 s of simulated time) inside the robot's
// controlStep, after Enki has updated the sensors for the tick: it steers toward its target
// with the true pose, slows and turns away when the front rays are short, keeps right of a
// robot seen close ahead, and escapes sideways when it has made no progress for 20 s.
//
// World::step(0.1, 1): one physics step per control tick. 1 is the default value of Enki's
// physicsOversampling argument and matches tavc's bench (sim.physics_substeps = 1 at
// dt_s = 0.1). A fourth command-line argument overrides it (Enki's Qt viewer uses 3 physics
// steps per 30 ms frame, i.e. 10 ms physics steps, which is 10 here).
//
// Usage: enki_bench [duration_s=600] [repeats=3] [n_robots=6] [physics_oversampling=1]
// Runs one untimed 30 s warm-up, then `repeats` timed runs of `duration_s` simulated seconds,
// each in a fresh world with the same seeded start, and prints one line of JSON on stdout.
//
// Build: g++ -O2 -std=c++17 enki_bench.cpp -lenki -o enki_bench
// (the headers live in /usr/include/enki and include each other as <enki/...>, so the default
// include path /usr/include is enough).

#include <enki/PhysicalEngine.h>
#include <enki/interactions/CircularCam.h>
#include <enki/robots/DifferentialWheeled.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <random>
#include <string>
#include <vector>

namespace {

// Arena and targets (cm).
constexpr double kArenaW = 1200.0;
constexpr double kArenaH = 800.0;
struct Circuit {
    Enki::Point source, sink;
};
const Circuit kCircuits[2] = {
    {Enki::Point(400.0, 800.0), Enki::Point(800.0, 0.0)},
    {Enki::Point(800.0, 800.0), Enki::Point(400.0, 0.0)},
};

// Robot (Pioneer 2-DX sized).
constexpr double kRadius = 22.0;       // cm
constexpr double kHeight = 25.0;       // cm, above both sensors so that robots see each other
constexpr double kMass = 15.0;         // Enki's mass is unitless; only ratios matter in collisions
constexpr double kWheelBase = 33.0;    // cm, distance between the driving wheels
constexpr double kMaxSpeed = 25.0;     // cm/s, top wheel (and forward) speed
constexpr double kMaxTurn = 1.2;       // rad/s, as tavc's pioneer2dx turn_rate_radps
constexpr double kMotorNoise = 0.0;    // Enki's relative wheel-speed noise, off
const Enki::Color kRobotColor(1.0, 0.0, 0.0);   // red robots ...
const Enki::Color kWallColor(0.5, 0.5, 0.5);    // ... against gray walls

// Sensors.
constexpr unsigned kScanPixels = 16;
constexpr double kScanHalfFov = M_PI / 2;        // 180 degrees
constexpr double kScanRange = 800.0;             // cm
constexpr double kSensorHeight = 20.0;           // cm
constexpr unsigned kCamPixels = 60;
constexpr double kCamHalfFov = 40.0 * M_PI / 180.0;  // 80 degrees
constexpr double kCamRange = 600.0;              // cm

// Behaviour (cm, s), after tavc's pioneer2dx behaviour section.
constexpr double kArriveDist = 50.0;   // arrival: centre within this of the target point
constexpr double kAvoidGap = 70.0;     // obstacles nearer than this (surface to surface) ahead are avoided
constexpr double kStopGap = 25.0;      // closer than this: stop and turn in place
constexpr double kKeepRightDist = 120.0;  // a robot seen this close (centre) ahead makes us keep right
constexpr double kStallS = 20.0;       // no progress_m closer to the goal in this long ...
constexpr double kProgress = 30.0;
constexpr double kEscapeS = 4.0;       // ... turns the robot away for this long

constexpr double kDt = 0.1;            // control period, s
constexpr double kWarmupS = 30.0;
constexpr unsigned kSeed = 12345;

bool isRobotColor(const Enki::Color& c) { return c.r() > 0.9 && c.g() < 0.1 && c.b() < 0.1; }

double clampd(double v, double lo, double hi) { return std::max(lo, std::min(hi, v)); }

class PioneerBot : public Enki::DifferentialWheeled {
  public:
    Enki::CircularCam scan;
    Enki::CircularCam camera;
    int circuit;
    bool toSource = true;
    long arrivals = 0;

    // Latest readings, for the controller.
    double ranges[kScanPixels];     // cm from the robot's centre along each scan ray
    double nearestRobotBearing = 0; // rad, + to the left; valid when nearestRobotDist is finite
    double nearestRobotDist = std::numeric_limits<double>::infinity();

    PioneerBot(int circuit, unsigned id)
        : DifferentialWheeled(kWheelBase, kMaxSpeed, kMotorNoise),
          scan(this, Enki::Vector(0, 0), kSensorHeight, 0.0, kScanHalfFov, kScanPixels),
          camera(this, Enki::Vector(0, 0), kSensorHeight, 0.0, kCamHalfFov, kCamPixels),
          circuit(circuit),
          rng(0x9E3779B9u * (id + 1)) {
        setCylindric(kRadius, kHeight, kMass);
        setColor(kRobotColor);
        scan.setRange(kScanRange);
        camera.setRange(kCamRange);
        addLocalInteraction(&scan);
        addLocalInteraction(&camera);
    }

    Enki::Point target() const { return toSource ? kCircuits[circuit].source : kCircuits[circuit].sink; }

    void controlStep(double dt) override {
        readSensors();
        control(dt);
        DifferentialWheeled::controlStep(dt);
    }

  private:
    std::minstd_rand rng;
    double bestDist = std::numeric_limits<double>::infinity();
    double sinceProgress = 0.0;
    double escapeLeft = 0.0;
    double escapeDir = 1.0;
    double avoidDir = 0.0;  // sticky turn direction while avoiding, 0 when clear

    static double scanAngle(unsigned k) { return -kScanHalfFov + k * (2 * kScanHalfFov / (kScanPixels - 1)); }
    static double camAngle(unsigned k) { return -kCamHalfFov + k * (2 * kCamHalfFov / (kCamPixels - 1)); }

    void readSensors() {
        for (unsigned k = 0; k < kScanPixels; ++k) {
            const double z2 = scan.zbuffer[k];
            double d = z2 >= std::numeric_limits<double>::max() ? kScanRange : std::sqrt(z2);
            // Enki draws a disc as its centre distance on every pixel it covers; take the
            // surface instead (exact on the ray through the centre, short elsewhere).
            if (isRobotColor(scan.image[k]))
                d -= kRadius;
            ranges[k] = clampd(d, 0.0, kScanRange);
        }
        // Colour camera: runs of robot-coloured pixels, nearest run's centre bearing.
        nearestRobotDist = std::numeric_limits<double>::infinity();
        unsigned k = 0;
        while (k < kCamPixels) {
            if (!isRobotColor(camera.image[k])) {
                ++k;
                continue;
            }
            const unsigned begin = k;
            double z2 = camera.zbuffer[k];
            while (k < kCamPixels && isRobotColor(camera.image[k]))
                z2 = std::min(z2, camera.zbuffer[k++]);
            const double d = std::sqrt(z2);
            if (d < nearestRobotDist) {
                nearestRobotDist = d;
                nearestRobotBearing = 0.5 * (camAngle(begin) + camAngle(k - 1));
            }
        }
    }

    double minRange(unsigned from, unsigned to) const {  // inclusive pixel range
        double m = kScanRange;
        for (unsigned k = from; k <= to; ++k)
            m = std::min(m, ranges[k]);
        return m;
    }

    void control(double dt) {
        const Enki::Vector toTarget = target() - pos;
        const double dist = toTarget.norm();
        if (dist < kArriveDist) {
            ++arrivals;
            toSource = !toSource;
            bestDist = std::numeric_limits<double>::infinity();
            sinceProgress = 0.0;
            escapeLeft = 0.0;
        }
        const Enki::Vector goal = target() - pos;
        const double goalDist = goal.norm();
        const double err = Enki::normalizeAngle(goal.angle() - angle);

        // Stall detection on distance to the goal.
        if (goalDist < bestDist - kProgress) {
            bestDist = goalDist;
            sinceProgress = 0.0;
        } else if ((sinceProgress += dt) > kStallS) {
            escapeLeft = kEscapeS;
            escapeDir = (rng() & 1) ? 1.0 : -1.0;
            bestDist = goalDist;
            sinceProgress = 0.0;
        }

        // Scan sectors: pixels 5..10 are -30 .. +30 deg (front), 2..6 right, 9..13 left.
        const double frontGap = minRange(5, 10) - kRadius;
        const double rightOpen = minRange(2, 6);
        const double leftOpen = minRange(9, 13);
        // The targets sit on walls: what lies at or beyond the target is not an obstacle.
        const bool blocked = frontGap < std::min(kAvoidGap, goalDist - kRadius - 15.0);

        double v, w;
        if (escapeLeft > 0.0) {
            escapeLeft -= dt;
            w = escapeDir * kMaxTurn;
            v = frontGap > kStopGap ? 0.5 * kMaxSpeed : 0.0;
        } else {
            v = kMaxSpeed * clampd(std::cos(err), 0.0, 1.0);
            w = clampd(1.5 * err, -kMaxTurn, kMaxTurn);
            if (blocked) {
                if (avoidDir == 0.0)
                    avoidDir = (leftOpen > rightOpen + 20.0) ? 1.0 : -1.0;  // tie: turn right
                const double f = clampd((frontGap - kStopGap) / (kAvoidGap - kStopGap), 0.0, 1.0);
                v *= f;
                w = f * w + (1.0 - f) * avoidDir * kMaxTurn;
            } else {
                avoidDir = 0.0;
            }
            // Keep right of a robot seen close ahead in the colour camera.
            if (nearestRobotDist < kKeepRightDist && std::fabs(nearestRobotBearing) < 30.0 * M_PI / 180.0) {
                const double closeness = 1.0 - nearestRobotDist / kKeepRightDist;
                w -= 0.8 * closeness;
                v *= 1.0 - 0.5 * closeness;
            }
        }
        w = clampd(w, -kMaxTurn, kMaxTurn);

        // (v, w) to wheel speeds, scaled down together to stay within the top wheel speed.
        double left = v - w * kWheelBase / 2, right = v + w * kWheelBase / 2;
        const double top = std::max(std::fabs(left), std::fabs(right));
        if (top > kMaxSpeed) {
            left *= kMaxSpeed / top;
            right *= kMaxSpeed / top;
        }
        leftSpeed = left;
        rightSpeed = right;
    }
};

struct Scene {
    Enki::World world{kArenaW, kArenaH, kWallColor};
    std::vector<PioneerBot*> robots;

    explicit Scene(unsigned nRobots) {
        world.setRandomSeed(kSeed);
        std::mt19937 gen(kSeed);
        std::uniform_real_distribution<double> ux(kRadius + 40.0, kArenaW - kRadius - 40.0);
        std::uniform_real_distribution<double> uy(kRadius + 40.0, kArenaH - kRadius - 40.0);
        std::uniform_real_distribution<double> ua(-M_PI, M_PI);
        for (unsigned i = 0; i < nRobots; ++i) {
            Enki::Point p;
            for (int attempt = 0;; ++attempt) {
                if (attempt > 100000) {
                    std::fprintf(stderr, "enki_bench: no room for %u robots\n", nRobots);
                    std::exit(2);
                }
                p = Enki::Point(ux(gen), uy(gen));
                bool ok = true;
                for (const PioneerBot* r : robots)
                    ok = ok && (r->pos - p).norm() > 2 * kRadius + 20.0;
                if (ok)
                    break;
            }
            auto* r = new PioneerBot(static_cast<int>(i % 2), i);
            r->pos = p;
            r->angle = ua(gen);
            robots.push_back(r);
            world.addObject(r);  // the world owns and deletes its objects
        }
    }

    long arrivals() const {
        long n = 0;
        for (const PioneerBot* r : robots)
            n += r->arrivals;
        return n;
    }
};

struct RunResult {
    double simS;
    double wallS;
    long arrivals;
};

RunResult runOnce(unsigned nRobots, double durationS, unsigned oversampling) {
    Scene scene(nRobots);
    const long ticks = std::max(1L, std::lround(durationS / kDt));
    const auto start = std::chrono::steady_clock::now();
    for (long t = 0; t < ticks; ++t)
        scene.world.step(kDt, oversampling);
    const auto stop = std::chrono::steady_clock::now();
    return {ticks * kDt, std::chrono::duration<double>(stop - start).count(), scene.arrivals()};
}

double median(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    const size_t n = v.size();
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

double argOr(int argc, char** argv, int i, double fallback) {
    if (argc <= i)
        return fallback;
    char* end = nullptr;
    const double v = std::strtod(argv[i], &end);
    if (end == argv[i] || *end != '\0') {
        std::fprintf(stderr, "enki_bench: argument %d is not a number: %s\n", i, argv[i]);
        std::exit(2);
    }
    return v;
}

}  // namespace

int main(int argc, char** argv) {
    const double durationS = argOr(argc, argv, 1, 600.0);
    const double repeatsArg = argOr(argc, argv, 2, 3);
    const double robotsArg = argOr(argc, argv, 3, 6);
    const double oversamplingArg = argOr(argc, argv, 4, 1);
    if (!(durationS > 0) || repeatsArg < 1 || robotsArg < 1 || robotsArg > 40 || oversamplingArg < 1) {
        std::fprintf(stderr,
                     "usage: enki_bench [duration_s>0 =600] [repeats>=1 =3] [n_robots 1..40 =6] "
                     "[physics_oversampling>=1 =1]\n");
        return 2;
    }
    const unsigned repeats = static_cast<unsigned>(repeatsArg);
    const unsigned nRobots = static_cast<unsigned>(robotsArg);
    const unsigned oversampling = static_cast<unsigned>(oversamplingArg);

    runOnce(nRobots, kWarmupS, oversampling);  // untimed warm-up
    std::vector<double> rtf;
    std::vector<long> arrivals;
    for (unsigned i = 0; i < repeats; ++i) {
        const RunResult r = runOnce(nRobots, durationS, oversampling);
        rtf.push_back(r.simS / r.wallS);
        arrivals.push_back(r.arrivals);
    }

    std::string runs, arr;
    char buf[64];
    for (unsigned i = 0; i < repeats; ++i) {
        std::snprintf(buf, sizeof buf, "%s%.1f", i ? ", " : "", rtf[i]);
        runs += buf;
        std::snprintf(buf, sizeof buf, "%s%ld", i ? ", " : "", arrivals[i]);
        arr += buf;
    }
    std::printf(
        "{\"simulator\": \"enki\", \"n_robots\": %u, \"duration_s\": %g, \"dt_s\": %g, \"physics_oversampling\": %u, "
        "\"scan_pixels\": %u, \"camera_pixels\": %u, \"sim_seconds_per_wall_second\": %.1f, \"runs\": [%s], "
        "\"arrivals\": %ld, \"arrivals_per_run\": [%s], \"units\": \"cm\", \"seed\": %u, "
        "\"measure\": \"simulated seconds of one world per wall second, median over runs, one core\"}\n",
        nRobots, durationS, kDt, oversampling, kScanPixels, kCamPixels, median(rtf), runs.c_str(), arrivals.back(),
        arr.c_str(), kSeed);
    return 0;
}
