// pick's application (issue 29): the checks every request passes (token, Host, Origin, paths), the
// marks saved at once with undo, the epipolar curves and predictions against the demo's truth,
// bad input named; and the real server: loopback only, refusals over a socket, Finish ends it.
#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <sstream>
#include <thread>
#include <tuple>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "formats/error.hpp"
#include "formats/tables.hpp"
#include "pick/server.hpp"
#include "tests/run_tool.hpp"
#include "tests/temp_dir.hpp"

namespace photomill::pick {
namespace {
namespace fs = std::filesystem;

const fs::path kDemo = fs::path(PHOTOMILL_SOURCE_DIR) / "data/demo";
const std::vector<std::string> kPhotos{"part_00.jpg", "part_01.jpg", "part_02.jpg"};
constexpr int kPort = 8123;  // handle() is called directly: no socket; the port only names the origin
const std::string kToken = "0123456789abcdef0123456789abcdef";

// The demo's true projections: image -> point id -> pixel.
std::map<std::string, std::map<PointId, Eigen::Vector2d>> truth() {
  std::ifstream in(kDemo / "observations.csv");
  std::map<std::string, std::map<PointId, Eigen::Vector2d>> t;
  for (const auto& o : read_observations(in, "observations.csv")) t[o.image][o.point_id] = {o.u_px, o.v_px};
  return t;
}

// Three demo photos, the true camera and (for those three) the true poses in a temp folder.
struct Job {
  test::TempDir dir;
  std::vector<std::string> photos;
  std::string camera, poses, output;
  Job() {
    for (const auto& p : kPhotos) {
      fs::copy_file(kDemo / p, dir.path() / p);
      photos.push_back((dir.path() / p).string());  // by path: poses.csv names only the file
    }
    camera = (dir.path() / "camera.yaml").string();
    fs::copy_file(kDemo / "camera.yaml", camera);
    poses = (dir.path() / "poses.csv").string();
    std::ifstream in(kDemo / "poses.csv");
    std::ofstream out(poses);
    for (std::string line; std::getline(in, line);) {
      if (line.rfind("image,", 0) == 0 || line.rfind("part_00", 0) == 0 || line.rfind("part_01", 0) == 0 || line.rfind("part_02", 0) == 0) {
        out << line << '\n';
      }
    }
    output = (dir.path() / "clicked.csv").string();
  }
  std::vector<Observation> saved() const {
    std::ifstream in(output);
    return read_observations(in, output);
  }
};

HttpRequest request(const std::string& method, const std::string& target, const std::string& body = "",
                    const std::map<std::string, std::string>& extra = {}) {
  std::string head = method + " " + target + " HTTP/1.1\r\nHost: 127.0.0.1:" + std::to_string(kPort);
  for (const auto& [k, v] : extra) head += "\r\n" + k + ": " + v;
  if (!body.empty()) head += "\r\nContent-Type: application/json";
  HttpRequest r;
  EXPECT_FALSE(parse_request_head(head, r)) << head;
  if (extra.count("Host")) r.headers["host"] = extra.at("Host");
  r.body = body;
  return r;
}

std::string with_token(const std::string& path) { return path + (path.find('?') == std::string::npos ? "?" : "&") + "token=" + kToken; }

class PickApp : public ::testing::Test {
protected:
  Job job;
  Session session{job.photos, job.camera, job.poses, job.output, {}};
  App app{session, kToken, kPort, Refine::None};
  HttpResponse call(const HttpRequest& r) {
    bool stop = false;
    return app.handle(r, &stop);
  }
  HttpResponse mark(std::size_t photo, PointId id, const Eigen::Vector2d& uv, const std::string& refine = "none") {
    std::ostringstream body;
    body.precision(17);
    body << "{\"photo\":" << photo << ",\"point_id\":" << id << ",\"u_px\":" << uv.x() << ",\"v_px\":" << uv.y()
         << ",\"refine\":\"" << refine << "\"}";
    return call(request("POST", with_token("/api/mark"), body.str()));
  }
};

TEST_F(PickApp, ServesThePageWithItsTokenAndTheStateWithTheCorrectToken) {
  const HttpResponse page = call(request("GET", with_token("/")));
  EXPECT_EQ(page.status, 200);
  EXPECT_NE(page.body.find("pick.js?token=" + kToken), std::string::npos);
  const HttpResponse state = call(request("GET", with_token("/api/state")));
  EXPECT_EQ(state.status, 200);
  EXPECT_NE(state.body.find("\"oriented\":true"), std::string::npos) << state.body;
  for (const char* path : {"/pick.js", "/pick.css", "/photo/2", "/thumb/0"}) EXPECT_EQ(call(request("GET", with_token(path))).status, 200) << path;
  const HttpResponse photo = call(request("GET", with_token("/photo/1")));
  EXPECT_EQ(photo.content_type, "image/jpeg");
  EXPECT_EQ(photo.body, test::read_file(kDemo / "part_01.jpg"));
}

TEST_F(PickApp, RefusesRequestsWithoutTheTokenFromAnotherOriginOrHost) {
  EXPECT_EQ(call(request("GET", "/")).status, 403);
  EXPECT_EQ(call(request("GET", "/api/state")).status, 403);
  EXPECT_EQ(call(request("GET", "/photo/0")).status, 403);
  EXPECT_EQ(call(request("GET", "/api/state?token=" + kToken.substr(0, 31) + "0")).status, 403);
  EXPECT_EQ(call(request("GET", "/api/state?token=")).status, 403);
  EXPECT_EQ(call(request("GET", with_token("/api/state"), "", {{"Origin", "http://evil.example"}})).status, 403);
  EXPECT_EQ(call(request("GET", with_token("/api/state"), "", {{"Origin", "http://127.0.0.1:9999"}})).status, 403);
  EXPECT_EQ(call(request("GET", with_token("/api/state"), "", {{"Sec-Fetch-Site", "cross-site"}})).status, 403);
  EXPECT_EQ(call(request("GET", with_token("/api/state"), "", {{"Host", "evil.example:8123"}})).status, 403);  // DNS rebinding
  EXPECT_EQ(call(request("GET", with_token("/api/state"), "", {{"Origin", "http://127.0.0.1:8123"}})).status, 200);
  // A page elsewhere posting a mark with a stolen token is still refused, and nothing is written.
  const HttpResponse r = call(request("POST", with_token("/api/mark"), R"({"photo":0,"point_id":1,"u_px":5,"v_px":5})",
                                      {{"Origin", "http://evil.example"}}));
  EXPECT_EQ(r.status, 403);
  EXPECT_FALSE(fs::exists(job.output));
}

TEST_F(PickApp, ServesNothingButItsRoutesWhateverThePath) {
  for (const std::string path : {"/../../etc/passwd", "/%2e%2e/%2e%2e/etc/passwd", "/photo/..%2f..%2fetc%2fpasswd",
                                 "/photo/../../../etc/passwd", "/photo/3", "/photo/-1", "/photo/1x", "/photo/", "/photo/01/",
                                 "/thumb/99999999999", "/camera.yaml", "/clicked.csv", "/part_00.jpg", "/etc/passwd"}) {
    const HttpResponse r = call(request("GET", with_token(path)));
    EXPECT_EQ(r.status, 404) << path;
    EXPECT_EQ(r.body.find("root:"), std::string::npos) << path;
  }
  HttpRequest encoded;
  EXPECT_TRUE(parse_request_head("GET /photo/%2 HTTP/1.1", encoded));  // a broken escape: 400 before any route
  EXPECT_EQ(call(request("GET", with_token("/api/mark"))).status, 405);
  HttpRequest no_json = request("POST", with_token("/api/mark"), "{}");
  no_json.headers.erase("content-type");
  EXPECT_EQ(call(no_json).status, 400);  // a plain form post (no CORS preflight) is refused
}

TEST_F(PickApp, SavesEveryMarkAtOnceAndUndoesIt) {
  EXPECT_EQ(mark(0, 56, {1089.5, 573.25}).status, 200);
  ASSERT_EQ(job.saved().size(), 1u);
  EXPECT_EQ(job.saved()[0], (Observation{job.photos[0], 56, 1089.5, 573.25}));
  EXPECT_EQ(mark(0, 56, {1090.5, 574.25}).status, 200);  // moved, not added
  ASSERT_EQ(job.saved().size(), 1u);
  EXPECT_EQ(job.saved()[0].u_px, 1090.5);
  EXPECT_EQ(mark(1, 56, {1217.8, 624.2}).status, 200);
  EXPECT_EQ(job.saved().size(), 2u);
  EXPECT_NE(call(request("POST", with_token("/api/delete"), R"({"photo":1,"point_id":56})")).body.find("true"), std::string::npos);
  EXPECT_EQ(job.saved().size(), 1u);
  EXPECT_NE(call(request("POST", with_token("/api/delete"), R"({"photo":1,"point_id":56})")).body.find("false"), std::string::npos);
  EXPECT_NE(call(request("POST", with_token("/api/undo"), "{}")).body.find("true"), std::string::npos);  // the delete
  EXPECT_EQ(job.saved().size(), 2u);
  EXPECT_NE(call(request("POST", with_token("/api/undo"), "{}")).body.find("true"), std::string::npos);  // the second photo's mark
  EXPECT_NE(call(request("POST", with_token("/api/undo"), "{}")).body.find("true"), std::string::npos);  // the move
  ASSERT_EQ(job.saved().size(), 1u);
  EXPECT_EQ(job.saved()[0].u_px, 1089.5);
  for (const auto& e : fs::directory_iterator(job.dir.path())) {
    EXPECT_EQ(e.path().filename().string().find(".tmp."), std::string::npos) << "temporary left: " << e.path();
  }
  // The file opens with its stamp (run id and row count), as every photomill CSV.
  EXPECT_EQ(test::read_file(job.output).rfind("# photomill run=", 0), 0u);
}

TEST(PickSession, AFailedSaveIsSaidAndFinishingFailsUnlessASaveSucceeds) {
  Job job;
  const fs::path folder = job.dir.path() / "out";
  fs::create_directories(folder);
  Session session(job.photos, std::nullopt, std::nullopt, (folder / "c.csv").string(), {});
  App app(session, kToken, kPort, Refine::None);
  bool stop = false;
  const auto mark = [&](PointId id) {
    return app.handle(request("POST", with_token("/api/mark"),
                              R"({"photo":0,"point_id":)" + std::to_string(id) + R"(,"u_px":10,"v_px":10})"), &stop);
  };
  EXPECT_EQ(mark(1).status, 200);
  fs::remove_all(folder);  // the folder gone (a disk unmounted): the next save fails
  const HttpResponse failed = mark(2);
  EXPECT_EQ(failed.status, 500);
  EXPECT_NE(failed.body.find("c.csv"), std::string::npos) << failed.body;
  EXPECT_FALSE(session.saved());
  EXPECT_EQ(app.handle(request("POST", with_token("/api/quit"), "{}"), &stop).status, 500);
  EXPECT_TRUE(stop);
  EXPECT_THROW(session.flush(), InputError);  // what main() does after the server stops: exit 1
  fs::create_directories(folder);             // back: the retry saves every mark
  session.flush();
  EXPECT_TRUE(session.saved());
  std::ifstream in(folder / "c.csv");
  EXPECT_EQ(read_observations(in, "c.csv").size(), 2u);
}

TEST_F(PickApp, RefusesMarksOutsideThePhotoAndMalformedBodies) {
  EXPECT_EQ(mark(0, 1, {-3, 5}).status, 422);
  EXPECT_EQ(mark(0, 1, {5, 1500}).status, 422);
  EXPECT_EQ(mark(3, 1, {5, 5}).status, 422);
  EXPECT_EQ(mark(0, 1, {5, 5}, "sharpen").status, 422);
  for (const std::string body : {"{", "[]", R"({"photo":0})", R"({"photo":0,"point_id":-1,"u_px":5,"v_px":5})",
                                 R"({"photo":0.5,"point_id":1,"u_px":5,"v_px":5})", R"({"photo":0,"point_id":1,"u_px":"5","v_px":5})"}) {
    EXPECT_EQ(call(request("POST", with_token("/api/mark"), body)).status, 422) << body;
  }
  EXPECT_FALSE(fs::exists(job.output));
}

TEST_F(PickApp, EpipolarCurvesAndPredictionsMeetTheTrueProjections) {
  const auto t = truth();
  double worst_curve = 0, worst_prediction = 0;
  for (PointId id = 56; id < 66; ++id) {
    session.mark(0, id, t.at("part_00.jpg").at(id), Refine::None);
    // One view: a curve in the others, no prediction.
    const Guide one = session.guide(id, 1);
    ASSERT_EQ(one.curves.size(), 1u);
    EXPECT_FALSE(one.predicted_px);
    const Eigen::Vector2d truth1 = t.at("part_01.jpg").at(id);
    double d = 1e9;
    for (const auto& line : one.curves[0].polylines) {
      for (std::size_t k = 1; k < line.size(); ++k) {
        const Eigen::Vector2d a = line[k - 1], ab = line[k] - line[k - 1];
        const double s = std::clamp((truth1 - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
        d = std::min(d, (a + s * ab - truth1).norm());
      }
    }
    worst_curve = std::max(worst_curve, d);
    session.mark(1, id, truth1, Refine::None);
    const Guide two = session.guide(id, 2);
    EXPECT_EQ(two.curves.size(), 2u);
    ASSERT_TRUE(two.predicted_px);
    worst_prediction = std::max(worst_prediction, (*two.predicted_px - t.at("part_02.jpg").at(id)).norm());
  }
  // Marks at the true projections: the curve (sampled, distortion included) and the prediction
  // pass through the truth up to the sampling's chords and the demo's rounding.
  EXPECT_LT(worst_curve, 0.01);
  EXPECT_LT(worst_prediction, 0.01);
  const HttpResponse state = call(request("GET", with_token("/api/state")));
  EXPECT_NE(state.body.find("\"residual_px\""), std::string::npos);
  EXPECT_NE(state.body.find("\"next_free_id\":100000"), std::string::npos) << state.body;  // marker ids stay below
}

TEST(PickSession, CornerRefinementFindsTheSaddleOfAChessboardCornerToAFewHundredthsOfAPixel) {
  // What corner refinement is for: a saddle (a chessboard corner, a drawn cross). The demo's
  // ChArUco board photos, clicked 0.8 px off the true corner: cornerSubPix lands within 0.1 px.
  // (On the corner of a marker, an L-corner with the code's cells beside it, it is biased by
  // 0.2-0.3 px or jumps to a neighbouring cell's corner: docs/pick.md; auto keeps zoomed clicks.)
  test::TempDir dir;
  const std::string photo = (dir.path() / "board_00.jpg").string();
  fs::copy_file(kDemo / "board_00.jpg", photo);
  Session session({photo}, std::nullopt, std::nullopt, (dir.path() / "c.csv").string(), {});
  std::ifstream in(kDemo / "board_observations.csv");
  double worst = 0;
  int n = 0;
  for (const auto& o : read_observations(in, "board_observations.csv")) {
    if (o.image != "board_00.jpg") continue;
    const Eigen::Vector2d truth(o.u_px, o.v_px);
    const MarkResult m = session.mark(0, o.point_id, truth + Eigen::Vector2d(0.8, -0.6), Refine::Corner);
    EXPECT_TRUE(m.refined) << o.point_id << ": " << m.note;
    worst = std::max(worst, (Eigen::Vector2d(m.observation.u_px, m.observation.v_px) - truth).norm());
    ++n;
  }
  std::cerr << "corner refinement from 1 px off: " << n << " board corners, worst " << worst << " px\n";
  EXPECT_GE(n, 20);
  EXPECT_LT(worst, 0.1);
  // Auto: corner refinement below zoom 4, the click as it is above.
  EXPECT_EQ(session.mark(0, 1000, {1000.25, 700.5}, Refine::Auto, 8).refine, Refine::None);
  EXPECT_EQ(session.mark(0, 1001, {1000.25, 700.5}, Refine::Auto, 1).refine, Refine::Corner);
}

// A disc of radius `r_px` centred at `centre` (OpenCV's pixel convention) on a flat background,
// rendered 8x supersampled and area-averaged, blurred (sigma 0.8 px) and with noise (sigma 1).
cv::Mat disc_image(const Eigen::Vector2d& centre, double r_px, double inside, double outside) {
  const int s = 8;
  cv::Mat big(300 * s, 400 * s, CV_32F, cv::Scalar(outside));
  // Supersample k covers [k/s, (k+1)/s) of the image area; its centre, in pixels, is (k + 0.5)/s - 0.5.
  cv::circle(big, cv::Point(static_cast<int>(std::lround((centre.x() + 0.5) * s * 16 - 8)),
                            static_cast<int>(std::lround((centre.y() + 0.5) * s * 16 - 8))),
             static_cast<int>(std::lround(r_px * s * 16)), cv::Scalar(inside), cv::FILLED, cv::LINE_8, 4);
  cv::Mat img, noise(300, 400, CV_32F);
  cv::resize(big, img, cv::Size(400, 300), 0, 0, cv::INTER_AREA);
  cv::GaussianBlur(img, img, cv::Size(0, 0), 0.8);
  cv::randn(noise, 0, 1);
  img += noise;
  cv::Mat out;
  img.convertTo(out, CV_8U);
  return out;
}

TEST(PickSession, BlobCentringFindsTheCentreOfADrawnDot) {
  test::TempDir dir;
  const std::vector<std::tuple<Eigen::Vector2d, double, double, double>> discs{
      {{150.37, 120.81}, 6, 40, 210}, {{201.62, 88.13}, 4, 230, 30}, {{90.5, 200.25}, 9.5, 20, 180}};
  std::vector<std::string> photos;
  for (std::size_t i = 0; i < discs.size(); ++i) {
    const auto& [c, r, in, out] = discs[i];
    photos.push_back((dir.path() / ("dot" + std::to_string(i) + ".png")).string());
    ASSERT_TRUE(cv::imwrite(photos.back(), disc_image(c, r, in, out)));
  }
  Session session(photos, std::nullopt, std::nullopt, (dir.path() / "c.csv").string(), {});
  double worst = 0;
  for (std::size_t i = 0; i < discs.size(); ++i) {
    const Eigen::Vector2d c = std::get<0>(discs[i]);
    const MarkResult m = session.mark(i, 100000, c + Eigen::Vector2d(1.7, -1.2), Refine::Blob);
    ASSERT_TRUE(m.refined) << m.note;
    worst = std::max(worst, (Eigen::Vector2d(m.observation.u_px, m.observation.v_px) - c).norm());
  }
  std::cerr << "blob centring from 2 px off: " << discs.size() << " discs, worst " << worst << " px\n";
  EXPECT_LT(worst, 0.05);
  // A blob larger than the window: refused, the click kept, the reason given.
  SessionOptions small;
  small.blob_half_window_px = 5;
  Session tight(photos, std::nullopt, std::nullopt, (dir.path() / "d.csv").string(), small);
  const MarkResult m = tight.mark(2, 100000, std::get<0>(discs[2]), Refine::Blob);
  EXPECT_FALSE(m.refined);
  EXPECT_NE(m.note.find("larger than the window"), std::string::npos) << m.note;
}

TEST(PickSession, LoadsAnExistingFileAndKeepsRowsOfOtherPhotos) {
  Job job;
  {
    std::ofstream out(job.output);
    out << "image,point_id,u_px,v_px\nelsewhere.jpg,100007,1,2\n" << job.photos[0] << ",3,10,20\n";
  }
  Session s(job.photos, std::nullopt, std::nullopt, job.output, {});
  EXPECT_FALSE(s.oriented());
  EXPECT_EQ(s.next_free_id(), 100008);  // above every clicked id, whichever photo holds it
  s.mark(1, 8, {30, 40}, Refine::None);
  const auto saved = job.saved();
  ASSERT_EQ(saved.size(), 3u);
  EXPECT_EQ(saved[0].image, "elsewhere.jpg");
  EXPECT_EQ(s.points().size(), 2u);  // the points of this job's photos
  EXPECT_TRUE(s.guide(8, 0).curves.empty());  // not oriented: no guidance
}

TEST(PickSession, NamesBadInput) {
  Job job;
  // A camera of another size than the photos.
  const std::string small = (job.dir.path() / "small.yaml").string();
  {
    std::string yaml = test::read_file(job.camera);
    const auto at = yaml.find("image_width: 2000");
    ASSERT_NE(at, std::string::npos) << yaml;
    yaml.replace(at, 17, "image_width: 1999");
    std::ofstream(small) << yaml;
  }
  try {
    Session s(job.photos, small, job.poses, job.output, {});
    FAIL() << "accepted a camera of another size";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("small.yaml"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("1999 x 1500"), std::string::npos) << e.what();
  }
  EXPECT_THROW(Session(job.photos, job.camera, std::nullopt, job.output, {}), UsageError);
  EXPECT_THROW(Session({job.photos[0], job.photos[0]}, std::nullopt, std::nullopt, job.output, {}), UsageError);
  const std::string other = (job.dir.path() / "other.csv").string();
  std::ofstream(other) << "image,qw,qx,qy,qz,tx_mm,ty_mm,tz_mm\nnot_here.jpg,1,0,0,0,0,0,500\n";
  try {
    Session s(job.photos, job.camera, other, job.output, {});
    FAIL() << "accepted poses of none of the photos";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("other.csv"), std::string::npos) << e.what();
  }
  const std::string broken = (job.dir.path() / "broken.jpg").string();
  std::ofstream(broken) << "not a photo";
  try {
    Session s({job.photos[0], broken}, std::nullopt, std::nullopt, job.output, {});
    FAIL() << "accepted a broken photo";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("broken.jpg"), std::string::npos) << e.what();
  }
  try {
    Session s(job.photos, std::nullopt, std::nullopt, (job.dir.path() / "no/such/folder/c.csv").string(), {});
    FAIL() << "accepted an output in a folder that does not exist";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("no/such/folder"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(job.output));
}

// --- the real server, over sockets --------------------------------------------------------------

// Sends `raw` to 127.0.0.1:port and returns the whole answer.
std::string send_request(int port, const std::string& raw) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(static_cast<std::uint16_t>(port));
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) {
    ::close(fd);
    return "";
  }
  ::send(fd, raw.data(), raw.size(), MSG_NOSIGNAL);
  std::string out;
  char buffer[4096];
  for (ssize_t n; (n = ::recv(fd, buffer, sizeof buffer, 0)) > 0;) out.append(buffer, static_cast<std::size_t>(n));
  ::close(fd);
  return out;
}

// The local addresses (hex "0100007F:1FBB") of the TCP sockets listening on `port`.
std::vector<std::string> listeners(int port) {
  std::vector<std::string> found;
  char hex_port[8];
  std::snprintf(hex_port, sizeof hex_port, "%04X", port);
  for (const char* table : {"/proc/net/tcp", "/proc/net/tcp6"}) {
    std::ifstream in(table);
    std::string line;
    std::getline(in, line);
    while (std::getline(in, line)) {
      std::istringstream f(line);
      std::string slot, local, remote, state;
      f >> slot >> local >> remote >> state;
      if (state == "0A" && local.size() > 5 && local.substr(local.size() - 4) == hex_port) found.push_back(local);
    }
  }
  return found;
}

TEST(PickServer, ListensOnLoopbackOnlyRefusesStrangersAndFinishesOnRequest) {
  Job job;
  int out_pipe[2];
  ASSERT_EQ(::pipe(out_pipe), 0);
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::dup2(out_pipe[1], 1);
    ::close(out_pipe[0]);
    const std::string exe = test::bin_path("pick");
    ::execl(exe.c_str(), exe.c_str(), job.photos[0].c_str(), job.photos[1].c_str(), "-q", "-o", job.output.c_str(),
            static_cast<char*>(nullptr));
    ::_exit(127);
  }
  ::close(out_pipe[1]);
  std::string url;
  char c;
  while (::read(out_pipe[0], &c, 1) == 1 && c != '\n') url += c;
  ::close(out_pipe[0]);
  ASSERT_EQ(url.rfind("http://127.0.0.1:", 0), 0u) << url;
  const int port = std::stoi(url.substr(17));
  const std::string token = url.substr(url.find("token=") + 6);
  EXPECT_EQ(token.size(), 32u);
  EXPECT_EQ(listeners(port), std::vector<std::string>{"0100007F:" + [&] {
              char h[8];
              std::snprintf(h, sizeof h, "%04X", port);
              return std::string(h);
            }()});
  const std::string host = "Host: 127.0.0.1:" + std::to_string(port) + "\r\n";
  EXPECT_EQ(send_request(port, "GET / HTTP/1.1\r\n" + host + "\r\n").rfind("HTTP/1.1 403", 0), 0u);
  EXPECT_EQ(send_request(port, "GET /%2e%2e/%2e%2e/etc/passwd?token=" + token + " HTTP/1.1\r\n" + host + "\r\n").rfind("HTTP/1.1 404", 0), 0u);
  EXPECT_EQ(send_request(port, "GET /api/state?token=" + token + " HTTP/1.1\r\n" + host + "Origin: http://evil.example\r\n\r\n")
                .rfind("HTTP/1.1 403", 0), 0u);
  EXPECT_EQ(send_request(port, "GET / HTTP/1.1\r\n" + host + "X: " + std::string(20000, 'a') + "\r\n\r\n").rfind("HTTP/1.1 431", 0), 0u);
  // A connection that sends nothing (a browser's preconnect) does not hold up the others.
  const int idle = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(static_cast<std::uint16_t>(port));
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ASSERT_EQ(::connect(idle, reinterpret_cast<sockaddr*>(&a), sizeof a), 0);
  const auto t0 = std::chrono::steady_clock::now();
  const std::string state = send_request(port, "GET /api/state?token=" + token + " HTTP/1.1\r\n" + host + "\r\n");
  EXPECT_EQ(state.rfind("HTTP/1.1 200", 0), 0u) << state;
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), kSocketTimeoutS / 2.0);
  ::close(idle);
  const std::string body = R"({"photo":1,"point_id":4,"u_px":100.25,"v_px":200.5,"refine":"none"})";
  const std::string marked = send_request(port, "POST /api/mark?token=" + token + " HTTP/1.1\r\n" + host +
                                                "Content-Type: application/json\r\nContent-Length: " + std::to_string(body.size()) +
                                                "\r\n\r\n" + body);
  EXPECT_EQ(marked.rfind("HTTP/1.1 200", 0), 0u) << marked;
  EXPECT_EQ(send_request(port, "POST /api/quit?token=" + token + " HTTP/1.1\r\n" + host +
                               "Content-Type: application/json\r\nContent-Length: 2\r\n\r\n{}").rfind("HTTP/1.1 200", 0), 0u);
  int status = 0;
  for (int i = 0; i < 100 && ::waitpid(pid, &status, WNOHANG) == 0; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  if (::waitpid(pid, &status, WNOHANG) == 0 && !WIFEXITED(status)) {
    ::kill(pid, SIGKILL);
    ::waitpid(pid, &status, 0);
    FAIL() << "pick did not finish after /api/quit";
  }
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
  EXPECT_EQ(job.saved(), (std::vector<Observation>{{job.photos[1], 4, 100.25, 200.5}}));
}

TEST(PickServer, RefusesBadUsageAndBadInputBeforeListening) {
  Job job;
  EXPECT_EQ(test::run_tool("pick", {job.photos[0]}).exit_code, 2);  // no -o
  EXPECT_EQ(test::run_tool("pick", {job.photos[0], "-o", "-"}).exit_code, 2);
  EXPECT_EQ(test::run_tool("pick", {job.photos[0], "-o", job.output, "--refine", "x"}).exit_code, 2);
  EXPECT_EQ(test::run_tool("pick", {job.photos[0], "-o", job.output, "--port", "70000"}).exit_code, 2);
  const auto r = test::run_tool("pick", {job.photos[0], "missing.jpg", "-o", job.output});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("missing.jpg"), std::string::npos) << r.err;
  EXPECT_EQ(r.out, "");
}

TEST(PickServer, ChecksEveryOptionAtParseTime) {
  Job job;
  const std::vector<std::pair<std::string, std::string>> bad{
      {"--port", "-1"}, {"--refine", "sharpen"}, {"--corner-half-window-px", "1"}, {"--lsm-half-window-px", "nan"},
      {"--max-refine-shift-px", "0"}, {"--blob-half-window-px", "2"}, {"--thumbnail-px", "5000"}, {"--first-id", "-1"}, {"--jobs", "-2"}};
  for (const auto& [option, value] : bad) {
    const auto r = test::run_tool("pick", {job.photos[0], "-o", job.output, option, value});
    EXPECT_NE(r.exit_code, 0) << option << " " << value;
    EXPECT_EQ(r.exit_code, 2) << option << " " << value;
    EXPECT_NE(r.err.find(option), std::string::npos) << r.err;
  }
  // --camera and --poses go together.
  EXPECT_EQ(test::run_tool("pick", {job.photos[0], "-o", job.output, "--camera", job.camera}).exit_code, 2);
  EXPECT_EQ(test::run_tool("pick", {job.photos[0], "-o", job.output, "--poses", job.poses}).exit_code, 2);
  EXPECT_FALSE(fs::exists(job.output));
}

}  // namespace
}  // namespace photomill::pick
