// A count of the holders of a bounded resource: long polls and event streams open at once (--max-waiting),
// figures being drawn at once (--figures-at-once).
#pragma once

#include <chrono>
#include <condition_variable>
#include <mutex>

namespace moreau::server {

class Budget {
 public:
  explicit Budget(int capacity) : capacity_(capacity) {}
  Budget(const Budget&) = delete;
  Budget& operator=(const Budget&) = delete;

  // Takes a place, or returns false at once when all are taken.
  bool try_take() {
    std::lock_guard lock(mu_);
    if (taken_ >= capacity_) return false;
    ++taken_;
    return true;
  }
  // Takes a place, waiting up to `timeout` for one.
  bool take(std::chrono::milliseconds timeout) {
    std::unique_lock lock(mu_);
    if (!cv_.wait_for(lock, timeout, [&] { return taken_ < capacity_; })) return false;
    ++taken_;
    return true;
  }
  void give_back() {
    {
      std::lock_guard lock(mu_);
      --taken_;
    }
    cv_.notify_one();
  }
  int taken() const {
    std::lock_guard lock(mu_);
    return taken_;
  }

 private:
  const int capacity_;
  mutable std::mutex mu_;
  std::condition_variable cv_;
  int taken_ = 0;
};

}  // namespace moreau::server
