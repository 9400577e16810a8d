// How big one message of a listing or a stream may grow. Nothing whose size
// grows with a sweep travels as one message (issue 28): a page of ListJobs
// and each batch of a server stream end once they hold kMessageBudgetBytes,
// so that a message stays far below gRPC's default 4 MiB limit, which the
// receiving side enforces whatever the sender allows (a client of a
// coordinator started with a larger --max-message-bytes still refuses more).
//
// A message may pass the budget by the one item that crossed it; an item
// (a job, an episode row with its at most 64 KiB of details, a study row) is
// bounded by the limits in docs/service.md, far below the remaining 3 MiB.
//
// Threading: a MessageBudget or BatchWriter belongs to one call.
#ifndef TOTALGRAD_SERVER_SERVICE_MESSAGE_BUDGET_H_
#define TOTALGRAD_SERVER_SERVICE_MESSAGE_BUDGET_H_

#include <google/protobuf/message_lite.h>
#include <grpcpp/support/sync_stream.h>

#include <cstddef>

namespace totalgrad::service {

inline constexpr size_t kMessageBudgetBytes = size_t{1} << 20;

// Counts the bytes of the items added to one message's repeated fields.
class MessageBudget {
 public:
  explicit MessageBudget(size_t budget_bytes = kMessageBudgetBytes) : budget_(budget_bytes) {}
  // One item of a repeated field: its size and at most 11 bytes of tag and
  // length prefix.
  void Add(const google::protobuf::MessageLite& item) {
    used_ += item.ByteSizeLong() + 11;
    ++items_;
  }
  bool Full() const { return used_ >= budget_; }
  size_t items() const { return items_; }
  void Reset() {
    used_ = 0;
    items_ = 0;
  }

 private:
  size_t budget_;
  size_t used_ = 0;
  size_t items_ = 0;
};

// Sends a server stream's items in batches of about the budget: append an
// item to batch(), then call Added with it; Finish sends the rest. Fields
// set on batch() before the first item (e.g. the sweep) travel in the first
// batch only. Every call returns false once the client has gone away.
template <typename Response>
class BatchWriter {
 public:
  explicit BatchWriter(grpc::ServerWriterInterface<Response>* writer,
                       size_t budget_bytes = kMessageBudgetBytes)
      : writer_(writer), budget_(budget_bytes) {}

  Response* batch() { return &batch_; }

  bool Added(const google::protobuf::MessageLite& item) {
    budget_.Add(item);
    return budget_.Full() ? Send() : true;
  }

  // Sends what is left; a stream with no item at all still sends one batch
  // (with the first batch's fields).
  bool Finish() { return budget_.items() > 0 || !sent_ ? Send() : true; }

 private:
  bool Send() {
    if (!writer_->Write(batch_)) return false;
    batch_.Clear();
    budget_.Reset();
    sent_ = true;
    return true;
  }

  grpc::ServerWriterInterface<Response>* writer_;
  MessageBudget budget_;
  Response batch_;
  bool sent_ = false;
};

}  // namespace totalgrad::service

#endif  // TOTALGRAD_SERVER_SERVICE_MESSAGE_BUDGET_H_
