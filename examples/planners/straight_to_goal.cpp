// A planner for `socialnav evaluate --policy exec:...` in C++, speaking the binary frames of
// docs/exec_protocol.md: the robot heads straight for its goal at its preferred speed, slowing down on the
// last step so as not to pass it (as socialnav's `linear` policy does). Standard library only:
//
//   c++ -O2 -std=c++17 -o straight_to_goal examples/planners/straight_to_goal.cpp
//   socialnav evaluate --policy exec:./straight_to_goal --preset wang2022
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <string>
#include <vector>

namespace {

// The number after "key": in a one-line JSON object (enough for the hello's flat fields).
double json_number(const std::string& line, const std::string& key) {
  const size_t at = line.find("\"" + key + "\"");
  if (at == std::string::npos) return NAN;
  return std::strtod(line.c_str() + line.find(':', at) + 1, nullptr);
}

bool read_exact(void* out, size_t n) { return std::fread(out, 1, n, stdin) == n; }

}  // namespace

int main() {
  std::string hello;
  if (!std::getline(std::cin, hello)) return 1;
  if (hello.find("\"socialnav-exec\"") == std::string::npos || json_number(hello, "version") != 1.0) {
    std::fprintf(stderr, "unsupported protocol: %s\n", hello.c_str());
    return 2;
  }
  const double dt = json_number(hello, "dt");
  const bool diff_drive = hello.find("\"diff_drive\"") != std::string::npos;
  const bool unicycle = diff_drive || hello.find("\"unicycle\"") != std::string::npos;
  std::printf("{\"protocol\": \"socialnav-exec\", \"version\": 1, \"format\": \"binary\", \"name\": \"straight_to_goal.cpp\"}\n");
  std::fflush(stdout);

  std::vector<double> robot, humans, time, walls, twist, actions;
  std::vector<uint8_t> mask, active;
  for (;;) {
    char magic[4];
    int32_t header[4];  // step, B, N, W
    if (!read_exact(magic, 4)) return 0;  // socialnav closed the stream: done
    if (std::memcmp(magic, "SNO1", 4) != 0 || !read_exact(header, sizeof header)) return 3;
    const size_t B = static_cast<size_t>(header[1]), N = static_cast<size_t>(header[2]);
    const size_t W = static_cast<size_t>(header[3]);
    robot.resize(B * 9);
    humans.resize(B * N * 5);
    mask.resize(B * N);
    active.resize(B);
    time.resize(B);
    walls.resize(W * 5);
    twist.resize(diff_drive ? B * 2 : 0);  // a differential drive's (v, omega) per row, after the walls
    if (!read_exact(robot.data(), robot.size() * 8) || !read_exact(humans.data(), humans.size() * 8) ||
        !read_exact(mask.data(), mask.size()) || !read_exact(active.data(), active.size()) ||
        !read_exact(time.data(), time.size() * 8) || !read_exact(walls.data(), walls.size() * 8) ||
        !read_exact(twist.data(), twist.size() * 8))
      return 4;
    actions.assign(B * 2, 0.0);
    for (size_t b = 0; b < B; ++b) {
      const double* r = &robot[b * 9];  // px, py, vx, vy, radius, gx, gy, v_pref, theta
      const double dx = r[5] - r[0], dy = r[6] - r[1];
      const double d = std::hypot(dx, dy);
      const double speed = std::min(r[7], d / dt);
      if (unicycle) {  // (v, d theta): turn towards the goal, then drive
        const double turn = std::remainder(std::atan2(dy, dx) - r[8], 2.0 * M_PI);
        // a differential drive drives only the speed along its heading (the world's limits apply)
        actions[2 * b] = diff_drive ? std::max(speed * std::cos(turn), 0.0) : speed;
        actions[2 * b + 1] = turn;
      } else if (d > 1e-9) {
        actions[2 * b] = speed * dx / d;
        actions[2 * b + 1] = speed * dy / d;
      }
    }
    const int32_t count = static_cast<int32_t>(B);
    std::fwrite("SNA1", 1, 4, stdout);
    std::fwrite(&count, 4, 1, stdout);
    std::fwrite(actions.data(), 8, actions.size(), stdout);
    std::fflush(stdout);
  }
}
