// A research tool, not a test: runs the real OpenSubdiv (Debian's libosd-dev, Far/Vtr) on a
// cage described on stdin and prints the uniformly refined level on stdout. It checks the claims
// of docs/research/*.md that Blender cannot check (holes, VTX_BOUNDARY_NONE, what is Blender's
// own and what is OpenSubdiv's). Build and run:
//
//   g++ -std=c++17 -O2 -o /tmp/osd_reference docs/research/osd_reference.cpp -losdCPU
//   /tmp/osd_reference < cage.txt
//
// Input, one record per line ("#" comments):
//   boundary B        Sdc::Options::VtxBoundaryInterpolation: 0 none, 1 edge-only, 2 edge-and-corner
//   fvar M            Sdc::Options::FVarLinearInterpolation: 0 none .. 5 all
//   levels L
//   v x y z           a vertex
//   f n i0 .. i(n-1)  a face
//   crease a b s      edge sharpness
//   corner v s        vertex sharpness
//   hole f            face tagged as a hole
//   uv u v            a face-varying value
//   fv i0 .. i(n-1)   the values of the corners of the next face in order (one line per face)
// Output: "v x y z" per level-L vertex, "f hole i0 i1 i2 i3" per level-L face (hole 0/1),
// "uv u v" per level-L face-varying value and "fv j0 j1 j2 j3" per level-L face.

#include <opensubdiv/far/primvarRefiner.h>
#include <opensubdiv/far/topologyDescriptor.h>
#include <opensubdiv/far/topologyRefinerFactory.h>

#include <cstdio>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

using namespace OpenSubdiv;

struct Point {
    float x[3];
    void Clear() { x[0] = x[1] = x[2] = 0.0f; }
    void AddWithWeight(Point const &p, float w) {
        for (int k = 0; k < 3; ++k) x[k] += w * p.x[k];
    }
};

struct Uv {
    float x[2];
    void Clear() { x[0] = x[1] = 0.0f; }
    void AddWithWeight(Uv const &p, float w) {
        for (int k = 0; k < 2; ++k) x[k] += w * p.x[k];
    }
};

int main() {
    int boundary = 1, fvar = 5, levels = 1;
    std::vector<Point> points;
    std::vector<int> sizes, indices, creasePairs, cornerVerts, holes, fvarIndices;
    std::vector<float> creaseWeights, cornerWeights;
    std::vector<Uv> uvs;
    std::string line;
    while (std::getline(std::cin, line)) {
        std::istringstream in(line);
        std::string key;
        if (!(in >> key) || key[0] == '#') continue;
        if (key == "boundary") in >> boundary;
        else if (key == "fvar") in >> fvar;
        else if (key == "levels") in >> levels;
        else if (key == "v") {
            Point p;
            in >> p.x[0] >> p.x[1] >> p.x[2];
            points.push_back(p);
        } else if (key == "f") {
            int n;
            in >> n;
            sizes.push_back(n);
            for (int i = 0; i < n; ++i) {
                int v;
                in >> v;
                indices.push_back(v);
            }
        } else if (key == "crease") {
            int a, b;
            float s;
            in >> a >> b >> s;
            creasePairs.push_back(a);
            creasePairs.push_back(b);
            creaseWeights.push_back(s);
        } else if (key == "corner") {
            int v;
            float s;
            in >> v >> s;
            cornerVerts.push_back(v);
            cornerWeights.push_back(s);
        } else if (key == "hole") {
            int f;
            in >> f;
            holes.push_back(f);
        } else if (key == "uv") {
            Uv u;
            in >> u.x[0] >> u.x[1];
            uvs.push_back(u);
        } else if (key == "fv") {
            int j;
            while (in >> j) fvarIndices.push_back(j);
        }
    }

    Far::TopologyDescriptor desc;
    desc.numVertices = (int)points.size();
    desc.numFaces = (int)sizes.size();
    desc.numVertsPerFace = sizes.data();
    desc.vertIndicesPerFace = indices.data();
    desc.numCreases = (int)creaseWeights.size();
    desc.creaseVertexIndexPairs = creasePairs.data();
    desc.creaseWeights = creaseWeights.data();
    desc.numCorners = (int)cornerWeights.size();
    desc.cornerVertexIndices = cornerVerts.data();
    desc.cornerWeights = cornerWeights.data();
    desc.numHoles = (int)holes.size();
    desc.holeIndices = holes.data();
    Far::TopologyDescriptor::FVarChannel channel;
    bool hasFvar = !uvs.empty() && fvarIndices.size() == indices.size();
    if (hasFvar) {
        channel.numValues = (int)uvs.size();
        channel.valueIndices = fvarIndices.data();
        desc.numFVarChannels = 1;
        desc.fvarChannels = &channel;
    }

    Sdc::Options options;
    options.SetVtxBoundaryInterpolation((Sdc::Options::VtxBoundaryInterpolation)boundary);
    options.SetFVarLinearInterpolation((Sdc::Options::FVarLinearInterpolation)fvar);
    options.SetCreasingMethod(Sdc::Options::CREASE_UNIFORM);
    using Factory = Far::TopologyRefinerFactory<Far::TopologyDescriptor>;
    Far::TopologyRefiner *refiner =
        Factory::Create(desc, Factory::Options(Sdc::SCHEME_CATMARK, options));
    if (!refiner) {
        std::fprintf(stderr, "OpenSubdiv refused the topology\n");
        return 1;
    }
    Far::TopologyRefiner::UniformOptions uniform(levels);
    uniform.fullTopologyInLastLevel = true;
    refiner->RefineUniform(uniform);

    std::vector<Point> verts(refiner->GetNumVerticesTotal());
    std::copy(points.begin(), points.end(), verts.begin());
    std::vector<Uv> values(hasFvar ? refiner->GetNumFVarValuesTotal(0) : 0);
    if (hasFvar) std::copy(uvs.begin(), uvs.end(), values.begin());
    Far::PrimvarRefiner primvar(*refiner);
    Point *src = verts.data();
    Uv *srcUv = values.data();
    for (int level = 1; level <= levels; ++level) {
        Point *dst = src + refiner->GetLevel(level - 1).GetNumVertices();
        primvar.Interpolate(level, src, dst);
        src = dst;
        if (hasFvar) {
            Uv *dstUv = srcUv + refiner->GetLevel(level - 1).GetNumFVarValues(0);
            primvar.InterpolateFaceVarying(level, srcUv, dstUv, 0);
            srcUv = dstUv;
        }
    }

    Far::TopologyLevel const &last = refiner->GetLevel(levels);
    for (int v = 0; v < last.GetNumVertices(); ++v)
        std::printf("v %.9g %.9g %.9g\n", src[v].x[0], src[v].x[1], src[v].x[2]);
    for (int f = 0; f < last.GetNumFaces(); ++f) {
        Far::ConstIndexArray fv = last.GetFaceVertices(f);
        std::printf("f %d", (int)last.IsFaceHole(f));
        for (int i = 0; i < fv.size(); ++i) std::printf(" %d", fv[i]);
        std::printf("\n");
    }
    if (hasFvar) {
        for (int i = 0; i < last.GetNumFVarValues(0); ++i)
            std::printf("uv %.9g %.9g\n", srcUv[i].x[0], srcUv[i].x[1]);
        for (int f = 0; f < last.GetNumFaces(); ++f) {
            Far::ConstIndexArray fv = last.GetFaceFVarValues(f, 0);
            std::printf("fv");
            for (int i = 0; i < fv.size(); ++i) std::printf(" %d", fv[i]);
            std::printf("\n");
        }
    }
    delete refiner;
    return 0;
}
