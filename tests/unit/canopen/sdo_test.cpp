// Expedited SDO coding: command specifier bytes, abort codes and texts, request/response parsing,
// unsupported segmented/block transfers and the client transaction.
#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

#include "pmlsm/canopen/bytes.hpp"
#include "pmlsm/canopen/sdo.hpp"

namespace {

using namespace pmlsm::canopen;

const NodeId kSdoNode(0x22);

CanFrame raw_frame(std::uint32_t id, std::array<std::uint8_t, 8> data, std::uint8_t dlc = 8) {
  CanFrame f = make_frame(id, dlc);
  f.data = data;
  return f;
}

TEST(SdoCodingTest, UploadRequestIs0x40) {
  const CanFrame f = sdo_upload_request(kSdoNode, 0x6041, 0);
  EXPECT_EQ(f.id, 0x622u);
  EXPECT_EQ(f.dlc, 8);
  const std::array<std::uint8_t, 8> expected{0x40, 0x41, 0x60, 0x00, 0, 0, 0, 0};
  EXPECT_EQ(f.data, expected);
}

TEST(SdoCodingTest, DownloadRequestCommandBytesBySize) {
  EXPECT_EQ(sdo_download_command(1), 0x2F);
  EXPECT_EQ(sdo_download_command(2), 0x2B);
  EXPECT_EQ(sdo_download_command(3), 0x27);
  EXPECT_EQ(sdo_download_command(4), 0x23);
  EXPECT_EQ(sdo_download_command(0), 0);
  EXPECT_EQ(sdo_download_command(5), 0);

  const CanFrame u8 = sdo_download(kSdoNode, 0x6060, 0, std::int8_t{10});
  EXPECT_EQ(u8.data, (std::array<std::uint8_t, 8>{0x2F, 0x60, 0x60, 0x00, 0x0A, 0, 0, 0}));
  const CanFrame i16 = sdo_download(kSdoNode, 0x6071, 0, std::int16_t{-2});
  EXPECT_EQ(i16.data, (std::array<std::uint8_t, 8>{0x2B, 0x71, 0x60, 0x00, 0xFE, 0xFF, 0, 0}));
  const auto three = sdo_download_request(kSdoNode, 0x2000, 1, 0x00ABCDEF, 3);
  ASSERT_TRUE(three.ok());
  EXPECT_EQ(three.value.data, (std::array<std::uint8_t, 8>{0x27, 0x00, 0x20, 0x01, 0xEF, 0xCD, 0xAB, 0}));
  const CanFrame u32 = sdo_download(kSdoNode, 0x1016, 1, std::uint32_t{0x12345678});
  EXPECT_EQ(u32.data, (std::array<std::uint8_t, 8>{0x23, 0x16, 0x10, 0x01, 0x78, 0x56, 0x34, 0x12}));
  EXPECT_EQ(u32.id, 0x622u);

  EXPECT_EQ(sdo_download_request(kSdoNode, 0x2000, 0, 1, 0).error, Error::kInvalidValue);
  EXPECT_EQ(sdo_download_request(kSdoNode, 0x2000, 0, 1, 5).error, Error::kInvalidValue);
  EXPECT_EQ(sdo_download_request(kSdoNode, 0x2000, 0, 0x100, 1).error, Error::kInvalidValue);
}

TEST(SdoCodingTest, UploadResponseCommandBytesBySize) {
  EXPECT_EQ(sdo_upload_response_command(1), 0x4F);
  EXPECT_EQ(sdo_upload_response_command(2), 0x4B);
  EXPECT_EQ(sdo_upload_response_command(3), 0x47);
  EXPECT_EQ(sdo_upload_response_command(4), 0x43);
  const auto r = sdo_upload_response(kSdoNode, 0x1000, 0, 0x00020192, 4);
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r.value.id, 0x5A2u);
  EXPECT_EQ(r.value.data, (std::array<std::uint8_t, 8>{0x43, 0x00, 0x10, 0x00, 0x92, 0x01, 0x02, 0x00}));
  EXPECT_EQ(sdo_upload_response(kSdoNode, 0x1000, 0, 0x1FF, 1).error, Error::kInvalidValue);
}

TEST(SdoCodingTest, DownloadResponseIs0x60AndAbortIs0x80) {
  const CanFrame ack = sdo_download_response(kSdoNode, 0x6040, 0);
  EXPECT_EQ(ack.id, 0x5A2u);
  EXPECT_EQ(ack.data, (std::array<std::uint8_t, 8>{0x60, 0x40, 0x60, 0x00, 0, 0, 0, 0}));
  const CanFrame server_abort = sdo_abort_response(kSdoNode, 0x6060, 0, 0x06090030);
  EXPECT_EQ(server_abort.id, 0x5A2u);
  EXPECT_EQ(server_abort.data, (std::array<std::uint8_t, 8>{0x80, 0x60, 0x60, 0x00, 0x30, 0x00, 0x09, 0x06}));
  const CanFrame client_abort = sdo_abort_request(kSdoNode, 0x1018, 2, 0x05040000);
  EXPECT_EQ(client_abort.id, 0x622u);
  EXPECT_EQ(client_abort.data, (std::array<std::uint8_t, 8>{0x80, 0x18, 0x10, 0x02, 0x00, 0x00, 0x04, 0x05}));
}

TEST(SdoAbortCodesTest, ValuesAndTextsOfCia301) {
  struct Row {
    std::uint32_t code;
    std::uint32_t value;
    const char* text;
  };
  const Row rows[] = {
      {kAbortToggleBit, 0x05030000, "toggle bit not alternated"},
      {kAbortTimeout, 0x05040000, "SDO protocol timed out"},
      {kAbortCommandSpecifier, 0x05040001, "client/server command specifier not valid or unknown"},
      {kAbortUnsupportedAccess, 0x06010000, "unsupported access to an object"},
      {kAbortReadWriteOnly, 0x06010001, "attempt to read a write only object"},
      {kAbortWriteReadOnly, 0x06010002, "attempt to write a read only object"},
      {kAbortObjectMissing, 0x06020000, "object does not exist in the object dictionary"},
      {kAbortNotMappable, 0x06040041, "object cannot be mapped to the PDO"},
      {kAbortPdoLength, 0x06040042, "the number and length of the objects to be mapped would exceed PDO length"},
      {kAbortLengthMismatch, 0x06070010, "data type does not match, length of service parameter does not match"},
      {kAbortSubindexMissing, 0x06090011, "sub-index does not exist"},
      {kAbortValueRange, 0x06090030, "invalid value for parameter (download only)"},
      {kAbortValueTooHigh, 0x06090031, "value of parameter written too high (download only)"},
      {kAbortValueTooLow, 0x06090032, "value of parameter written too low (download only)"},
      {kAbortGeneral, 0x08000000, "general error"},
      {kAbortDataNotStored, 0x08000020, "data cannot be transferred or stored to the application"},
      {kAbortLocalControl, 0x08000021,
       "data cannot be transferred or stored to the application because of local control"},
      {kAbortDeviceState, 0x08000022,
       "data cannot be transferred or stored to the application because of the present device state"},
  };
  for (const Row& row : rows) {
    EXPECT_EQ(row.code, row.value);
    EXPECT_STREQ(describe(row.code), row.text) << std::hex << row.code;
  }
  EXPECT_STREQ(describe(0), "no error");
  EXPECT_STREQ(describe(0x12345678), "unknown abort code");
}

TEST(SdoRequestParseTest, UploadDownloadAbort) {
  const auto up = parse_sdo_request(sdo_upload_request(kSdoNode, 0x6064, 0));
  ASSERT_TRUE(up.ok()) << up.detail;
  EXPECT_EQ(up.value.kind, SdoRequestKind::kUpload);
  EXPECT_EQ(up.value.node_id, 0x22);
  EXPECT_EQ(up.value.index, 0x6064);
  EXPECT_EQ(up.value.subindex, 0);

  for (std::uint8_t size = 1; size <= 4; ++size) {
    const std::uint32_t value = 0xA1B2C3D4U & (size == 4 ? 0xFFFFFFFFU : ((1U << (8 * size)) - 1));
    const auto down = parse_sdo_request(sdo_download_request(kSdoNode, 0x2001, 3, value, size).value);
    ASSERT_TRUE(down.ok()) << down.detail;
    EXPECT_EQ(down.value.kind, SdoRequestKind::kDownload);
    EXPECT_EQ(down.value.index, 0x2001);
    EXPECT_EQ(down.value.subindex, 3);
    EXPECT_EQ(down.value.data.size, size);
    EXPECT_EQ(down.value.data.data, value);
  }
  // e = 1, s = 0: size not indicated; the unused bytes of a sized request are masked off.
  const auto unsized = parse_sdo_request(raw_frame(0x622, {0x22, 0x40, 0x60, 0x00, 0x0F, 0x00, 0x00, 0x00}));
  ASSERT_TRUE(unsized.ok());
  EXPECT_EQ(unsized.value.data.size, 0);
  EXPECT_EQ(unsized.value.data.data, 0x0Fu);
  const auto masked = parse_sdo_request(raw_frame(0x622, {0x2F, 0x60, 0x60, 0x00, 0x0A, 0xEE, 0xEE, 0xEE}));
  ASSERT_TRUE(masked.ok());
  EXPECT_EQ(masked.value.data.data, 0x0Au);

  const auto abort = parse_sdo_request(sdo_abort_request(kSdoNode, 0x6040, 0, kAbortTimeout));
  ASSERT_TRUE(abort.ok());
  EXPECT_EQ(abort.value.kind, SdoRequestKind::kAbort);
  EXPECT_EQ(abort.value.abort_code, kAbortTimeout);
}

TEST(SdoRequestParseTest, UnsupportedAndMalformedRequestsGiveErrorsWithAbort0x05040001) {
  struct Row {
    std::uint8_t command;
    Error error;
  };
  const Row rows[] = {
      {0x21, Error::kSegmentedNotSupported},  // initiate download, e = 0, s = 1
      {0x20, Error::kSegmentedNotSupported},  // initiate download, e = 0, s = 0
      {0x00, Error::kSegmentedNotSupported},  // download segment
      {0x60, Error::kSegmentedNotSupported},  // upload segment
      {0xA0, Error::kBlockNotSupported},      // block upload
      {0xC0, Error::kBlockNotSupported},      // block download
      {0xE0, Error::kUnknownCommand},         // ccs 7
  };
  for (const Row& row : rows) {
    const auto r = parse_sdo_request(raw_frame(0x622, {row.command, 0x40, 0x60, 0x00, 0, 0, 0, 0}));
    EXPECT_EQ(r.error, row.error) << std::hex << int(row.command);
    EXPECT_EQ(r.abort_code, kAbortCommandSpecifier);
    EXPECT_EQ(r.value.index, 0x6040);  // multiplexer kept for the abort
  }
  CanFrame short_frame = sdo_upload_request(kSdoNode, 0x6041, 0);
  short_frame.dlc = 4;
  const auto r = parse_sdo_request(short_frame);
  EXPECT_EQ(r.error, Error::kWrongDlc);
  EXPECT_STREQ(r.detail, "SDO request: DLC must be 8");
  EXPECT_EQ(r.value.index, 0x6041);
  EXPECT_EQ(parse_sdo_request(sdo_download_response(kSdoNode, 0x6041, 0)).error, Error::kWrongCobId);
}

TEST(SdoResponseParseTest, UploadDownloadAbort) {
  const auto up = parse_sdo_response(sdo_upload_response(kSdoNode, 0x6041, 0, 0x0237, 2).value);
  ASSERT_TRUE(up.ok());
  EXPECT_EQ(up.value.kind, SdoResponseKind::kUpload);
  EXPECT_EQ(up.value.node_id, 0x22);
  EXPECT_EQ(up.value.data.size, 2);
  EXPECT_EQ(up.value.data.data, 0x0237u);
  const auto down = parse_sdo_response(sdo_download_response(kSdoNode, 0x6040, 0));
  ASSERT_TRUE(down.ok());
  EXPECT_EQ(down.value.kind, SdoResponseKind::kDownload);
  const auto abort = parse_sdo_response(sdo_abort_response(kSdoNode, 0x6060, 0, kAbortValueRange));
  ASSERT_TRUE(abort.ok());
  EXPECT_EQ(abort.value.kind, SdoResponseKind::kAbort);
  EXPECT_EQ(abort.value.abort_code, kAbortValueRange);
}

TEST(SdoResponseParseTest, SegmentedUploadIsReportedNotSupported) {
  // 0x41: scs 2, e = 0, s = 1: the server starts a segmented upload of 20 bytes.
  const auto r = parse_sdo_response(raw_frame(0x5A2, {0x41, 0x08, 0x10, 0x00, 20, 0, 0, 0}));
  EXPECT_EQ(r.error, Error::kSegmentedNotSupported);
  EXPECT_STREQ(to_string(r.error), "segmented transfer not supported");
  EXPECT_EQ(std::string(r.detail).rfind("segmented transfer not supported", 0), 0u);
  EXPECT_EQ(r.value.index, 0x1008);
  for (std::uint8_t command : {0x00, 0x20}) {  // segment responses
    EXPECT_EQ(parse_sdo_response(raw_frame(0x5A2, {command, 0, 0, 0, 0, 0, 0, 0})).error,
              Error::kSegmentedNotSupported);
  }
  EXPECT_EQ(parse_sdo_response(raw_frame(0x5A2, {0xA4, 0, 0, 0, 0, 0, 0, 0})).error, Error::kBlockNotSupported);
  EXPECT_EQ(parse_sdo_response(raw_frame(0x5A2, {0xC0, 0, 0, 0, 0, 0, 0, 0})).error, Error::kBlockNotSupported);
  EXPECT_EQ(parse_sdo_response(raw_frame(0x5A2, {0xE0, 0, 0, 0, 0, 0, 0, 0})).error, Error::kUnknownCommand);
  EXPECT_EQ(parse_sdo_response(raw_frame(0x5A2, {0x60, 0, 0, 0}, 4)).error, Error::kWrongDlc);
  EXPECT_EQ(parse_sdo_response(sdo_upload_request(kSdoNode, 0, 0)).error, Error::kWrongCobId);
}

TEST(SdoClientTest, UploadDownloadAndBusy) {
  SdoClient client(kSdoNode, 100);
  const auto request = client.upload(0x6041, 0, 0);
  ASSERT_TRUE(request.ok());
  EXPECT_EQ(request.value.data[0], 0x40);
  EXPECT_TRUE(client.busy());
  EXPECT_EQ(client.upload(0x6041, 0, 1).error, Error::kBusy);
  // Another node's response and unrelated frames are not ours.
  EXPECT_EQ(client.on_frame(sdo_upload_response(NodeId(3), 0x6041, 0, 1, 2).value).kind, SdoClientEventKind::kNone);
  const SdoClientEvent e = client.on_frame(sdo_upload_response(kSdoNode, 0x6041, 0, 0x0237, 2).value);
  EXPECT_EQ(e.kind, SdoClientEventKind::kUploaded);
  EXPECT_EQ(e.data.data, 0x0237u);
  EXPECT_FALSE(client.busy());

  ASSERT_TRUE(client.download(0x6060, 0, SdoData{10, 1}, 5).ok());
  EXPECT_EQ(client.on_frame(sdo_download_response(kSdoNode, 0x6060, 0)).kind, SdoClientEventKind::kDownloaded);
  EXPECT_EQ(client.download(0x6060, 0, SdoData{10, 0}, 5).error, Error::kInvalidValue);
  EXPECT_FALSE(client.busy());
  EXPECT_THROW(SdoClient(kSdoNode, 0), std::invalid_argument);
}

TEST(SdoClientTest, AbortMismatchSegmentedAndTimeout) {
  SdoClient client(kSdoNode, 100);
  client.download(0x6060, 0, SdoData{3, 1}, 0);
  SdoClientEvent e = client.on_frame(sdo_abort_response(kSdoNode, 0x6060, 0, kAbortValueRange));
  EXPECT_EQ(e.kind, SdoClientEventKind::kAborted);
  EXPECT_EQ(e.abort_code, kAbortValueRange);
  EXPECT_STREQ(e.detail, "invalid value for parameter (download only)");

  client.upload(0x6041, 0, 0);
  e = client.on_frame(sdo_upload_response(kSdoNode, 0x6064, 0, 1, 4).value);
  EXPECT_EQ(e.kind, SdoClientEventKind::kFailed);
  EXPECT_EQ(e.error, Error::kUnexpectedResponse);

  client.upload(0x6041, 0, 0);
  e = client.on_frame(sdo_download_response(kSdoNode, 0x6041, 0));
  EXPECT_EQ(e.kind, SdoClientEventKind::kFailed);
  EXPECT_EQ(e.error, Error::kUnexpectedResponse);

  client.upload(0x1008, 0, 0);
  e = client.on_frame(raw_frame(0x5A2, {0x41, 0x08, 0x10, 0x00, 20, 0, 0, 0}));
  EXPECT_EQ(e.kind, SdoClientEventKind::kFailed);
  EXPECT_EQ(e.error, Error::kSegmentedNotSupported);
  ASSERT_TRUE(e.send_abort);
  EXPECT_EQ(e.abort_frame.id, 0x622u);
  EXPECT_EQ(e.abort_frame.data, (std::array<std::uint8_t, 8>{0x80, 0x08, 0x10, 0x00, 0x01, 0x00, 0x04, 0x05}));

  client.upload(0x6041, 0, 1000);
  EXPECT_EQ(client.poll(1100).kind, SdoClientEventKind::kNone);
  e = client.poll(1101);
  EXPECT_EQ(e.kind, SdoClientEventKind::kTimedOut);
  EXPECT_EQ(e.abort_code, kAbortTimeout);
  ASSERT_TRUE(e.send_abort);
  EXPECT_EQ(get_u32_le(e.abort_frame.data, 4), kAbortTimeout);
  EXPECT_FALSE(client.busy());
  EXPECT_EQ(client.poll(5000).kind, SdoClientEventKind::kNone);
}

}  // namespace
