// Writes the trajectory as CSV while the run goes: t, h, q_1..q_n, v_1..v_n, energy. Rows are
// formatted with std::to_chars (shortest round-trip form) into a large buffer, so output costs little and
// memory does not grow with the number of steps.
#pragma once

#include <cstdio>
#include <string>
#include <vector>

#include "moreau/core/observer.h"

namespace moreau::scene {

class TrajectoryCsvWriter : public RunObserver {
 public:
  // Opens `path` and writes the header. Throws std::runtime_error if the file cannot be written.
  TrajectoryCsvWriter(const std::string& path, const std::vector<std::string>& q_names,
                      const std::vector<std::string>& v_names);
  ~TrajectoryCsvWriter() override;
  void on_sample(const Sample& s) override;
  // Flushes and closes; throws if anything failed to be written (a full disk, say).
  void close();
  double seconds() const { return seconds_; }  // time spent formatting and writing

 private:
  void put(double value);
  void flush_buffer();
  std::FILE* file_ = nullptr;
  std::string path_;
  std::vector<char> buffer_;
  std::size_t used_ = 0;
  bool failed_ = false;
  int error_ = 0;  // errno of the first failed write
  double seconds_ = 0.0;
};

// Runs several observers as one.
class ObserverFan : public RunObserver {
 public:
  void add(RunObserver* o) {
    if (o) observers_.push_back(o);
  }
  void on_sample(const Sample& s) override {
    for (auto* o : observers_) o->on_sample(s);
  }
  bool keep_going(std::int64_t step, double t) override {
    bool go = true;
    for (auto* o : observers_) go = o->keep_going(step, t) && go;
    return go;
  }

 private:
  std::vector<RunObserver*> observers_;
};

}  // namespace moreau::scene
