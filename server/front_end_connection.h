// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// The front end's state of one connection, shared by its event loop (front_end.cpp) and its
// reading and writing (front_end_io.cpp). Not part of the front end's interface.

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>

#include "server/front_end.h"

namespace stlrefine::server {

struct FrontEnd::Connection {
  enum class State {
    Head,    // reading the request head
    Body,    // reading Content-Length bytes of body
    Answer,  // writing an answer; input is dropped
    Linger,  // answered and shut down for writing: input is dropped until EOF or timeout
  };
  int fd = -1;
  std::size_t slot = 0;
  State state = State::Head;
  std::chrono::steady_clock::time_point accepted, deadline;
  // Body and Answer: bytes moved since window_start (the minimum-rate check).
  std::chrono::steady_clock::time_point window_start;
  std::uint64_t window_bytes = 0;
  std::string in;                        // the head so far
  std::size_t scanned = 0;               // in[0, scanned) holds no "\r\n\r\n"
  std::unique_ptr<ReadRequest> request;  // Body: the request being read
  std::uint64_t body_expected = 0;
  std::function<std::string(std::uint64_t)> reserve_body;
  Answer out;  // Answer: what is written
  std::uint64_t sent = 0;
  // A made body's current piece: its bytes [piece_at, piece_at + piece.size()).
  std::string piece;
  std::uint64_t piece_at = 0;
  // A stream (Answer::stream): nothing to send until it is pulled again; no more to pull.
  bool stream_idle = false;
  bool stream_ended = false;
  std::shared_ptr<void> hold;  // released once the answer is written
  bool in_probe_lane = false;
  bool read_closed = false;  // the client half-closed while its answer is written
  std::uint32_t events = 0;  // registered with epoll
  bool registered = false;
  std::string remote_ip;
  int remote_port = 0;
};

}  // namespace stlrefine::server
