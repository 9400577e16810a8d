// The coordinator's clocks (runtime/clock.h, shared with the worker),
// under the names the scheduler and the service have always used. Lease
// expiry is judged on the coordinator's monotonic clock only, never on a
// worker's clock and never on the wall clock (which NTP or an operator may
// step).
#ifndef TOTALGRAD_SERVER_SCHEDULER_CLOCK_H_
#define TOTALGRAD_SERVER_SCHEDULER_CLOCK_H_

#include "runtime/clock.h"

namespace totalgrad::scheduler {

using ::totalgrad::Clock;
using ::totalgrad::FakeClock;
using ::totalgrad::SystemClock;

}  // namespace totalgrad::scheduler

#endif  // TOTALGRAD_SERVER_SCHEDULER_CLOCK_H_
