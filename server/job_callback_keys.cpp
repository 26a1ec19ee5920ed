// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
// A tenant's callback key from its API key, as the operator computes it (stlrefined
// --print-callback-key): the tenant id exactly as JobStore::tenant_of makes it, from the
// data directory's secret, then tenant_callback_key.
#include <openssl/evp.h>
#include <openssl/hmac.h>

#include <stdexcept>

#include "server/job_callbacks.h"
#include "server/job_record.h"

namespace stlrefine::server {

std::string job_files::tenant_id(const std::array<unsigned char, kTenantKeyBytes>& tenant_key,
                                 std::string_view api_key) {
  unsigned char mac[EVP_MAX_MD_SIZE];
  unsigned int size = 0;
  if (!HMAC(EVP_sha256(), tenant_key.data(), static_cast<int>(tenant_key.size()),
            reinterpret_cast<const unsigned char*>(api_key.empty() ? "" : api_key.data()),
            api_key.size(), mac, &size) ||
      size < 16)
    throw std::runtime_error("HMAC-SHA256 failed");
  return hex(mac, 16);
}

std::string callback_key_of_api_key(const std::filesystem::path& data_dir,
                                    const std::string& secret, std::string_view api_key) {
  if (secret.empty()) throw std::runtime_error("no callback secret (--callback-secret)");
  if (api_key.empty()) return tenant_callback_key(secret, "");  // a daemon without API keys
  // As the daemon's first start would: the key made now is the one it will read.
  std::filesystem::create_directories(data_dir);
  return tenant_callback_key(secret,
                             job_files::tenant_id(job_files::load_tenant_key(data_dir), api_key));
}

}  // namespace stlrefine::server
